//! Instanced geometry: *objects* (triangle meshes in their own space, stored once) and
//! *instances* placing an object in the world with an affine transform and an optional
//! material override (`[[mesh]] name = ...` and `[[instance]]` in TOML).
//!
//! The acceleration side ([`crate::accel::InstanceAccel`]) builds one bottom-level
//! structure per object and a top-level BVH over the instances' world boxes; rays are
//! moved into object space there. This file holds the scene data, its validation, and
//! the surface geometry of an instanced hit (world point with its error bound, normals
//! by the inverse transpose).
//!
//! # Precision
//!
//! Transforms follow pbrt-v4 (`Transform::operator()(Point3fi)`, Pharr, Jakob, Humphreys,
//! *Physically Based Rendering*, 4th ed., §6.8.5): a point `p` with error `e` maps to
//! `M p` with error `γ3 (|m00 x| + |m01 y| + |m02 z| + |m03|) + (γ3 + 1)(|m00| e_x +
//! |m01| e_y + |m02| e_z)` per row. The object-space hit point comes from the
//! barycentrics ([`triangle_point`]) with its own bound, so the world point's bound is
//! the sum. One more term is added: a ray spawned from the world point is mapped *back*
//! into object space for the next query, which rounds its origin again (`γ3` per row of
//! the inverse, plus one rounding of the inverse's own entries); that error, mapped to
//! the world by `|M|`, is added to `p_error` ([`Affine::back_transform_margin`]), so the
//! offset origin ([`crate::geometry::offset_ray_origin`]) stays on its side of the
//! surface after the round trip. pbrt-v4 instead moves the transformed origin forward
//! along the ray by its error (`Transform::ApplyInverse(Ray, tMax)`), which changes the
//! ray's parametrisation; here `t` means the same in both spaces (origin and direction
//! go through the same affine map, the direction is not normalised).

use super::TriangleMesh;
use crate::geometry::{Aabb, gamma, triangle_point};
use glam::{Mat4, Vec3};

/// An affine map as the top three rows of a 4x4 matrix, row-major: `x' = m[0][0] x +
/// m[0][1] y + m[0][2] z + m[0][3]`, evaluated in exactly that order (Rust never fuses
/// into FMA), which the error bounds assume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    pub m: [[f32; 4]; 3],
}

impl Affine {
    pub const IDENTITY: Affine = Affine {
        m: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// The affine part of a column-major glam matrix (its last row is ignored).
    pub fn from_mat4(t: Mat4) -> Affine {
        let r = |i: usize| {
            let row = t.row(i);
            [row.x, row.y, row.z, row.w]
        };
        Affine {
            m: [r(0), r(1), r(2)],
        }
    }

    /// As a glam matrix with last row `0 0 0 1`.
    pub fn to_mat4(&self) -> Mat4 {
        let m = &self.m;
        Mat4::from_cols_array_2d(&[
            [m[0][0], m[1][0], m[2][0], 0.0],
            [m[0][1], m[1][1], m[2][1], 0.0],
            [m[0][2], m[1][2], m[2][2], 0.0],
            [m[0][3], m[1][3], m[2][3], 1.0],
        ])
    }

    /// Determinant of the linear part.
    pub fn determinant(&self) -> f64 {
        self.to_mat4().as_dmat4().determinant()
    }

    /// The inverse map, computed in f64 and rounded once per entry; `None` if the
    /// linear part is singular or the inverse is not finite in f32.
    pub fn inverse(&self) -> Option<Affine> {
        let d = self.to_mat4().as_dmat4();
        let det = d.determinant();
        if !(det.is_finite() && det != 0.0) {
            return None;
        }
        let inv = Affine::from_mat4(d.inverse().as_mat4());
        inv.m.iter().flatten().all(|x| x.is_finite()).then_some(inv)
    }

    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        let r = |i: usize| {
            let m = &self.m[i];
            m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3]
        };
        Vec3::new(r(0), r(1), r(2))
    }

    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        let r = |i: usize| {
            let m = &self.m[i];
            m[0] * v.x + m[1] * v.y + m[2] * v.z
        };
        Vec3::new(r(0), r(1), r(2))
    }

    /// `|L| v` for the absolute linear part `|L|` (for error propagation).
    #[inline]
    pub fn abs_vector(&self, v: Vec3) -> Vec3 {
        let r = |i: usize| {
            let m = &self.m[i];
            m[0].abs() * v.x + m[1].abs() * v.y + m[2].abs() * v.z
        };
        Vec3::new(r(0), r(1), r(2))
    }

    /// `L^T v`: applied with the *inverse* map's linear part it transforms normals
    /// (the inverse transpose).
    #[inline]
    pub fn transpose_vector(&self, v: Vec3) -> Vec3 {
        let m = &self.m;
        Vec3::new(
            m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
            m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
            m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z,
        )
    }

    /// The image of the point `p` (per-component error `e`) and its error bound
    /// (pbrt-v4 `Transform::operator()(Point3fi)`).
    #[inline]
    pub fn point_with_error(&self, p: Vec3, e: Vec3) -> (Vec3, Vec3) {
        let q = self.point(p);
        let err = |i: usize| {
            let m = &self.m[i];
            gamma(3) * ((m[0] * p.x).abs() + (m[1] * p.y).abs() + (m[2] * p.z).abs() + m[3].abs())
                + (gamma(3) + 1.0) * (m[0].abs() * e.x + m[1].abs() * e.y + m[2].abs() * e.z)
        };
        (q, Vec3::new(err(0), err(1), err(2)))
    }

    /// World-space bound on how far a ray origin near the world point `p` (error
    /// `p_error`) moves when it is offset ([`crate::geometry::offset_ray_origin`]) and
    /// then mapped into object space by `inverse` (this map's inverse, as rounded) and
    /// back by `self` in exact arithmetic: the rounding of `inverse.point(o)` is at most
    /// `γ3 (|L⁻¹| |o| + |t⁻¹|)` per row, and the inverse's entries are each one rounding
    /// off the exact inverse, another `u` of the same sum, so `γ4` in all (taken as `γ5`
    /// for evaluating the bound); `|L|` maps it to the world. `|o|` is bounded by
    /// `|p| + 2 ‖p_error‖₁`: the offset moves `p` by at most `‖p_error‖₁ (1 + γ8)` and a
    /// few ulps.
    pub fn back_transform_margin(&self, inverse: &Affine, p: Vec3, p_error: Vec3) -> Vec3 {
        let reach = p_error.x + p_error.y + p_error.z;
        let o = p.abs() + Vec3::splat(2.0 * reach);
        let obj = |i: usize| {
            let m = &inverse.m[i];
            gamma(5) * (m[0].abs() * o.x + m[1].abs() * o.y + m[2].abs() * o.z + m[3].abs())
        };
        self.abs_vector(Vec3::new(obj(0), obj(1), obj(2))) * (1.0 + gamma(4))
    }

    /// World bounds of an object-space box: its eight corners mapped and padded by
    /// their rounding error, so the box contains every mapped point.
    pub fn bounds(&self, b: &Aabb) -> Aabb {
        let mut out = Aabb::EMPTY;
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let (q, e) = self.point_with_error(c, Vec3::ZERO);
            out.grow(q - e);
            out.grow(q + e);
        }
        out
    }
}

/// One placement of an object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`InstanceSet::objects`].
    pub object: u32,
    /// Object space to world space.
    pub to_world: Affine,
    /// World space to object space (`to_world`'s inverse, rounded once).
    pub to_object: Affine,
    /// Material for every triangle of this instance; `None` keeps the object's own.
    pub material: Option<u32>,
}

/// Objects and their instances.
#[derive(Clone, Debug, Default)]
pub struct InstanceSet {
    /// Object meshes in object space; material ids index the scene's materials.
    pub objects: Vec<TriangleMesh>,
    /// Object names (TOML `[[mesh]] name`), one per object.
    pub names: Vec<String>,
    pub instances: Vec<Instance>,
}

/// The geometry of a surface point, as the integrator needs it (world space): the
/// point and its error bound, the unit geometric normal (outward as the object is
/// wound, whatever the transform's handedness), the unit shading normal, the material,
/// and for smooth-shaded triangles their world corners and unit vertex normals (for
/// the shadow-terminator base point).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub p: Vec3,
    pub p_error: Vec3,
    pub n_geometric: Vec3,
    pub n_shading: Vec3,
    pub material: u32,
    pub smooth: Option<([Vec3; 3], [Vec3; 3])>,
}

impl SurfacePoint {
    /// `(p, p_error, n_geometric, n_shading, material, smooth)`.
    #[allow(clippy::type_complexity)]
    pub fn parts(self) -> (Vec3, Vec3, Vec3, Vec3, u32, Option<([Vec3; 3], [Vec3; 3])>) {
        (
            self.p,
            self.p_error,
            self.n_geometric,
            self.n_shading,
            self.material,
            self.smooth,
        )
    }
}

impl InstanceSet {
    pub fn is_empty(&self) -> bool {
        self.instances.is_empty()
    }

    /// Adds an object (a mesh in its own space) and returns its index.
    pub fn add_object(&mut self, name: &str, mesh: TriangleMesh) -> u32 {
        self.objects.push(mesh);
        self.names.push(name.to_string());
        (self.objects.len() - 1) as u32
    }

    /// The object called `name`.
    pub fn object_id(&self, name: &str) -> Option<u32> {
        self.names.iter().position(|n| n == name).map(|i| i as u32)
    }

    /// Places object `object` with `to_world`; `Err` with a reason if the transform is
    /// not finite or not invertible.
    pub fn add_instance(
        &mut self,
        object: u32,
        to_world: Mat4,
        material: Option<u32>,
    ) -> Result<u32, String> {
        let to_world = Affine::from_mat4(to_world);
        let to_object = check_transform(&to_world)?;
        self.instances.push(Instance {
            object,
            to_world,
            to_object,
            material,
        });
        Ok((self.instances.len() - 1) as u32)
    }

    /// Triangles drawn (each instance counts its object's triangles).
    pub fn instanced_triangles(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.objects[i.object as usize].len())
            .sum()
    }

    /// Object-space bounds of object `o`.
    pub fn object_bounds(&self, o: usize) -> Aabb {
        let m = &self.objects[o];
        let mut b = Aabb::EMPTY;
        for i in 0..m.vertex_count() {
            b.grow(m.vertex(i as u32));
        }
        b
    }

    /// World bounds of every instance, in instance order.
    pub fn world_bounds(&self) -> Vec<Aabb> {
        let object_bounds: Vec<Aabb> = (0..self.objects.len())
            .map(|o| self.object_bounds(o))
            .collect();
        self.instances
            .iter()
            .map(|i| {
                let b = &object_bounds[i.object as usize];
                if b.is_empty() {
                    Aabb::EMPTY
                } else {
                    i.to_world.bounds(b)
                }
            })
            .collect()
    }

    /// The material of triangle `prim` of instance `inst`.
    pub fn material(&self, inst: u32, prim: u32) -> u32 {
        let i = &self.instances[inst as usize];
        i.material
            .unwrap_or(self.objects[i.object as usize].material[prim as usize])
    }

    /// Whether material `id` is drawn by some instance.
    pub fn uses_material(&self, id: u32) -> bool {
        self.instances.iter().any(|i| match i.material {
            Some(m) => m == id,
            None => self.objects[i.object as usize].material.contains(&id),
        })
    }

    /// Whether some instanced object has vertex normals.
    pub fn has_shading_normals(&self) -> bool {
        self.instances.iter().any(|i| {
            let m = &self.objects[i.object as usize];
            m.has_normals() && !m.is_empty()
        })
    }

    /// The world-space surface at barycentrics `(u, v)` of triangle `prim` of instance
    /// `inst`: the object-space point ([`triangle_point`]) mapped with its error, plus
    /// the back-transform margin ([`Affine::back_transform_margin`]); normals by the
    /// inverse transpose (vertex normals mapped and normalised one by one, then
    /// interpolated, as a mesh baked into world space would be).
    pub fn surface(&self, inst: u32, prim: u32, u: f32, v: f32) -> SurfacePoint {
        let i = &self.instances[inst as usize];
        let mesh = &self.objects[i.object as usize];
        let t = prim as usize;
        let (p_obj, e_obj) = triangle_point(mesh.corners(t), u, v);
        let (p, e) = i.to_world.point_with_error(p_obj, e_obj);
        let p_error = e + i.to_world.back_transform_margin(&i.to_object, p, e);
        let normal = |n: Vec3| i.to_object.transpose_vector(n).normalize_or_zero();
        let [a, b, c] = mesh.corners(t);
        let n_geometric = normal((b - a).cross(c - a));
        let world_normals = mesh.vertex_normals(t).map(|ns| ns.map(normal));
        let n_shading = match world_normals {
            Some([n0, n1, n2]) => {
                let s = ((1.0 - u - v) * n0 + u * n1 + v * n2).normalize_or_zero();
                if s == Vec3::ZERO { n_geometric } else { s }
            }
            None => n_geometric,
        };
        let smooth = world_normals
            .filter(|ns| ns.iter().all(|n| *n != Vec3::ZERO))
            .map(|ns| (mesh.corners(t).map(|q| i.to_world.point(q)), ns));
        SurfacePoint {
            p,
            p_error,
            n_geometric,
            n_shading,
            material: i.material.unwrap_or(mesh.material[t]),
            smooth,
        }
    }

    /// Checks objects, instances and material ids (`nmat` materials exist).
    pub fn validate(&self, nmat: u32) -> Result<(), String> {
        if self.names.len() != self.objects.len() {
            return Err("one name per object is needed".into());
        }
        for (o, m) in self.objects.iter().enumerate() {
            let name = &self.names[o];
            let nv = m.vertex_count() as u32;
            if let Some(p) = (0..nv).map(|i| m.vertex(i)).find(|p| !p.is_finite()) {
                return Err(format!("object `{name}`: vertex {p} is not finite"));
            }
            if m.has_normals() && m.nxs.len() != m.xs.len() {
                return Err(format!(
                    "object `{name}`: normal count differs from vertex count"
                ));
            }
            for t in 0..m.len() {
                if [m.i0[t], m.i1[t], m.i2[t]].iter().any(|&i| i >= nv) {
                    return Err(format!(
                        "object `{name}`: triangle {t} uses a vertex beyond {nv}"
                    ));
                }
                if m.material[t] >= nmat {
                    return Err(format!(
                        "object `{name}`: triangle {t} uses material {}, but there are {nmat}",
                        m.material[t]
                    ));
                }
            }
        }
        for (k, i) in self.instances.iter().enumerate() {
            if i.object as usize >= self.objects.len() {
                return Err(format!(
                    "instance {k} names object {}, but there are {}",
                    i.object,
                    self.objects.len()
                ));
            }
            check_transform(&i.to_world).map_err(|e| format!("instance {k}: {e}"))?;
            if i.material.is_some_and(|m| m >= nmat) {
                return Err(format!(
                    "instance {k} uses material {}, but there are {nmat}",
                    i.material.unwrap_or(0)
                ));
            }
        }
        Ok(())
    }
}

/// The inverse of a valid instance transform: finite entries and an invertible linear
/// part whose inverse is finite in f32.
fn check_transform(to_world: &Affine) -> Result<Affine, String> {
    if !to_world.m.iter().flatten().all(|x| x.is_finite()) {
        return Err("the transform has a non-finite entry".into());
    }
    to_world
        .inverse()
        .ok_or_else(|| "the transform is singular (its linear part has no inverse)".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn sample_transform() -> Mat4 {
        Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 3.0),
            Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0),
            Vec3::new(1e4, -3.0, 7.5),
        )
    }

    #[test]
    fn affine_matches_glam_and_round_trips() {
        let m = sample_transform();
        let a = Affine::from_mat4(m);
        assert_eq!(a.to_mat4(), m);
        let inv = a.inverse().unwrap();
        let p = Vec3::new(0.25, -1.5, 3.0);
        // glam evaluates in another order: agreement to a few ulps of the largest
        // term (1e4), not bit for bit.
        assert!((a.point(p) - m.transform_point3(p)).abs().max_element() < 1e-2);
        let back = inv.point(a.point(p));
        assert!((back - p).abs().max_element() < 1e-3, "{back} vs {p}");
    }

    #[test]
    fn point_error_bound_contains_the_exact_image() {
        // The exact image (f64) of an exactly represented point lies inside the bound.
        let a = Affine::from_mat4(sample_transform());
        let mut worst = 0.0f64;
        for k in 0..1000 {
            let f = |s: u32| ((k * 7919 + s * 104_729) % 2001) as f32 / 1000.0 - 1.0;
            let p = Vec3::new(f(1), f(2), f(3)) * 10.0;
            let (q, e) = a.point_with_error(p, Vec3::ZERO);
            for i in 0..3 {
                let m = &a.m[i];
                let exact = m[0] as f64 * p.x as f64
                    + m[1] as f64 * p.y as f64
                    + m[2] as f64 * p.z as f64
                    + m[3] as f64;
                let dev = (q[i] as f64 - exact).abs();
                assert!(dev <= e[i] as f64, "row {i}: {dev} > {}", e[i]);
                worst = worst.max(dev / e[i] as f64);
            }
        }
        assert!(worst > 0.0, "the test never saw a rounding error");
    }

    #[test]
    fn singular_and_non_finite_transforms_are_rejected() {
        let mut s = InstanceSet::default();
        assert!(
            s.add_instance(0, Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)), None)
                .is_err()
        );
        let mut m = Mat4::IDENTITY;
        m.w_axis.x = f32::NAN;
        assert!(s.add_instance(0, m, None).is_err());
        assert!(s.add_instance(0, sample_transform(), None).is_ok());
    }
}
