//! Texture coordinates at a hit and cut-outs (alpha-tested surfaces).
//!
//! A material with a cut-out map (MTL `map_d`, TOML `alpha_texture`) is absent where
//! the map's coverage is below [`ALPHA_CUTOFF`](crate::texture::ALPHA_CUTOFF): every
//! ray, camera, reflected, refracted and shadow, passes through there. This is the
//! any-hit alpha test of Embree's intersection filters (`RTCFilterFunctionN`, which
//! rejects a candidate so traversal continues behind it) and of OptiX's any-hit
//! programs. The plain queries (`closest_hit`, `any_hit`, the SIMD packet kernels) are
//! left as they are: a hit they return on a cut-out material is tested here, and only
//! when it falls in a hole is the ray traced again with the filtered query
//! ([`SceneAccel::filtered_hit`]), which offers every candidate to a filter rejecting
//! holes. Scenes without cut-outs never run that test.

use crate::accel::{PrimRef, QueryOptions, SceneAccel, SceneHit};
use crate::geometry::Ray;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Texture coordinates of a direction from a sphere's centre (`n` unit length):
/// `u` the longitude, `0.5 + atan2(z, x) / 2π`: 0 (and 1) at -X, 0.25 at -Z, 0.5 at
/// +X, 0.75 at +Z; `v` the latitude, 0 at the
/// south pole (-Y) and 1 at the north pole (+Y), so an equirectangular image
/// (row 0 at the top) wraps the sphere upright.
#[inline]
pub fn sphere_uv(n: Vec3) -> Vec2 {
    let u = 0.5 + n.z.atan2(n.x) * (0.5 * FRAC_1_PI);
    let v = 0.5 + n.y.clamp(-1.0, 1.0).asin() * FRAC_1_PI;
    Vec2::new(u, v)
}

/// Texture coordinates of the hit `hit` of `ray`: interpolated per-vertex `uv` on a
/// triangle (zero for a mesh without them), [`sphere_uv`] on a sphere (the direction
/// from the centre to the hit point, at the ray's time for a moving one); the object's
/// `uv` on an instance; zero on an infinite plane.
pub fn hit_uv(scene: &Scene, ray: &Ray, hit: &SceneHit) -> Vec2 {
    let sphere = |c: Vec3| sphere_uv((ray.at(hit.t) - c).normalize_or_zero());
    match hit.prim {
        PrimRef::Triangle(t) => scene.mesh.uv_at(t as usize, hit.u, hit.v),
        PrimRef::MovingTriangle(t) => scene.motion.mesh.uv_at(t as usize, hit.u, hit.v),
        PrimRef::Sphere(s) => sphere(scene.spheres.center(s as usize)),
        PrimRef::MovingSphere(s) => sphere(scene.motion.sphere_center(s as usize, ray.time)),
        PrimRef::Instance { instance, prim } => {
            let object = scene.instances.instances[instance as usize].object as usize;
            scene.instances.objects[object].uv_at(prim as usize, hit.u, hit.v)
        }
        // Infinite planes carry no texture coordinates.
        PrimRef::Plane(_) => Vec2::ZERO,
    }
}

/// Whether any material of the scene has a cut-out map.
pub fn has_cutouts(scene: &Scene) -> bool {
    scene.materials.iter().any(|m| m.has_cutout())
}

/// Whether the hit lies in a hole of a cut-out material.
#[inline]
pub fn is_hole(scene: &Scene, ray: &Ray, hit: &SceneHit) -> bool {
    let m = &scene.materials[super::shadow::material_of(scene, hit.prim) as usize];
    m.has_cutout() && m.textures.is_hole(hit_uv(scene, ray, hit))
}

/// The nearest hit of `ray` that is not in a hole, given `hit`, the plain query's
/// nearest hit: `hit` itself when it is solid (the common case, no second query),
/// else the filtered closest-hit query that rejects every candidate in a hole.
/// Returns whether a second query ran, for the ray counts.
pub fn solid_hit(
    scene: &Scene,
    accel: &SceneAccel,
    ray: &Ray,
    hit: SceneHit,
) -> (Option<SceneHit>, bool) {
    if !is_hole(scene, ray, &hit) {
        return (Some(hit), false);
    }
    let opts = QueryOptions {
        cull_back_faces: false,
        any: false,
    };
    let found = accel.filtered_hit(ray, opts, &mut |c| !is_hole(scene, ray, &c.hit));
    (found, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_uv_at_the_axes() {
        let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 1e-6;
        assert!(close(sphere_uv(Vec3::X), Vec2::new(0.5, 0.5)));
        assert!(close(sphere_uv(Vec3::Z), Vec2::new(0.75, 0.5)));
        assert!(close(sphere_uv(-Vec3::Z), Vec2::new(0.25, 0.5)));
        assert_eq!(sphere_uv(Vec3::Y).y, 1.0);
        assert_eq!(sphere_uv(-Vec3::Y).y, 0.0);
    }
}
