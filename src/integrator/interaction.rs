//! Surface interactions: what a hit is at the surface (point with its error bound,
//! geometric and shading normals, material, side, shadow-ray base point), rebuilt from
//! the primitive the ray hit.

use crate::accel::{PrimRef, SceneHit};
use crate::geometry::terminator::shadow_terminator_point;
use crate::geometry::{Ray, sphere_point, triangle_point};
use crate::scene::{Scene, TriangleMesh};
use glam::{Vec2, Vec3};

/// What the shader needs to know about a hit.
///
/// Both normals are unit length and face the side the incident ray came from, so
/// shading never has to ask which way a triangle was wound; `front_face` keeps the
/// lost information (the ray hit the outside: triangle winding or sphere exterior),
/// which is what tells a dielectric whether the ray enters or leaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    /// Per-component bound on the distance of `p` from the true surface (the box
    /// `p ± p_error` contains a surface point): what every secondary ray origin is
    /// offset by ([`offset_ray_origin`](crate::geometry::offset_ray_origin),
    /// [`spawn_ray_to`](crate::geometry::spawn_ray_to)).
    pub p_error: Vec3,
    pub n_geometric: Vec3,
    pub n_shading: Vec3,
    pub material: u32,
    pub front_face: bool,
    /// On a triangle with vertex normals, the base point of its shadow rays: `p`
    /// lifted onto the smooth surface the normals describe ([`shadow_terminator_point`],
    /// Hanika 2021), so that a coarse mesh shaded smooth neither shadows itself in
    /// facets near the terminator nor drops lights that are above the shading normal's
    /// horizon but below the flat facet. `None` elsewhere (shadow rays leave from `p`,
    /// and a light below the geometric surface contributes nothing).
    pub p_shadow: Option<Vec3>,
    /// Texture coordinates at the hit ([`super::texturing::hit_uv`]); zero when the
    /// material has no texture (nothing reads them then).
    pub uv: glam::Vec2,
}

impl SurfaceInteraction {
    /// The hit point is rebuilt from the primitive, not as `o + t d`: `t` carries the
    /// rounding error of the whole intersection test scaled by the ray length, whereas
    /// barycentric interpolation of the corners ([`triangle_point`]) or reprojection
    /// onto a sphere ([`sphere_point`]) lands within a bound of the surface that is
    /// computed with the point and kept in `p_error` (pbrt-v4's `Point3fi`).
    ///
    /// Moving primitives are placed at the ray's time exactly as the intersection
    /// kernels place them (`v + time * velocity`, the same f32 operations), and a ray
    /// spawned here keeps that time, so the error is relative to the placed corners
    /// (or centre): placing them adds nothing the next ray does not see identically.
    pub fn new(scene: &Scene, ray: &Ray, hit: &SceneHit) -> Self {
        // Translation leaves normals unchanged, so both kinds of triangle (and of
        // sphere) share one rule. The last element: corners and vertex normals, for the
        // shadow-ray base point.
        let on_triangle = |mesh: &TriangleMesh, t: usize, corners: [Vec3; 3]| {
            let (p, p_error) = triangle_point(corners, hit.u, hit.v);
            let (ng, ns) = (
                mesh.geometric_normal(t),
                mesh.shading_normal(t, hit.u, hit.v),
            );
            let smooth = mesh.vertex_normals(t).map(|n| (corners, n));
            (p, p_error, ng, ns, mesh.material[t], smooth)
        };
        let on_sphere = |center: Vec3, radius: f32, material: u32| {
            let (p, p_error, n) = sphere_point(center, radius, ray.at(hit.t));
            (p, p_error, n, n, material, None)
        };
        let (motion, spheres) = (&scene.motion, &scene.spheres);
        let (p, p_error, ng, ns, material, smooth) = match hit.prim {
            PrimRef::Triangle(t) => {
                on_triangle(&scene.mesh, t as usize, scene.mesh.corners(t as usize))
            }
            PrimRef::Sphere(s) => {
                let s = s as usize;
                on_sphere(spheres.center(s), spheres.radius[s], spheres.material[s])
            }
            PrimRef::MovingTriangle(t) => {
                let t = t as usize;
                on_triangle(&motion.mesh, t, motion.triangle_corners(t, ray.time))
            }
            PrimRef::MovingSphere(s) => {
                let s = s as usize;
                let center = motion.sphere_center(s, ray.time);
                on_sphere(center, motion.spheres.radius[s], motion.spheres.material[s])
            }
            // Instances and infinite planes: world-space surface with its error bound.
            PrimRef::Instance { instance, prim } => scene
                .instances
                .surface(instance, prim, hit.u, hit.v)
                .parts(),
            PrimRef::Plane(i) => scene.planes[i as usize].surface(ray, hit.t).parts(),
        };
        // A degenerate triangle or a hit at a sphere's centre has no normal; facing the
        // ray keeps every later formula finite.
        let ng = if ng == Vec3::ZERO {
            -ray.dir.normalize()
        } else {
            ng
        };
        let front_face = ray.dir.dot(ng) < 0.0;
        let ng = if front_face { ng } else { -ng };
        // Interpolated normals may disagree with the true surface (coarse meshes,
        // inconsistent winding); keep them on the geometric side.
        let flip = ns.dot(ng) < 0.0;
        let ns = if flip { -ns } else { ns };
        let p_shadow = smooth.map(|(corners, normals)| {
            let normals = if flip { normals.map(|n| -n) } else { normals };
            let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
            shadow_terminator_point(p, corners, normals, bary, ng)
        });
        SurfaceInteraction {
            p,
            p_error,
            n_geometric: ng,
            n_shading: ns,
            material,
            front_face,
            p_shadow,
            // Only a textured material looks its uv up: a sphere's costs an atan2 and an
            // asin, which an untextured scene should not pay at every hit.
            uv: if scene.materials[material as usize].textures.is_empty() {
                Vec2::ZERO
            } else {
                super::texturing::hit_uv(scene, ray, hit)
            },
        }
    }
}
