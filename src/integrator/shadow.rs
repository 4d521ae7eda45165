//! Transmitted shadows: how much of a light's radiance a shadow ray carries past
//! transmissive (glass) surfaces.
//!
//! A shadow ray that meets a dielectric is attenuated by that surface's
//! `transmission` colour and goes on, once per surface crossed (a glass sphere
//! crossed through its middle filters twice, entering and leaving, as the refracted
//! camera ray through it is weighted twice); any other surface blocks it. This is
//! POV-Ray's default behaviour for filtering and transmitting pigments ("filtered
//! shadows": light through glass, no caustics and no bending of the shadow ray).
//! Fresnel is left out, so an `ior` 1.0, `transmission` 1 object, which is invisible
//! to camera rays, casts no shadow either; at other `ior`s the shadow is slightly too
//! light at grazing angles, where the surface would reflect part of the light.
//!
//! **Default on** (`[render] transmitted_shadows`, `--transmitted-shadows`): a fully
//! black shadow under clear glass is the artefact users report, and POV-Ray, which
//! users compare against, filters by default. Off gives the classic Whitted image
//! where every surface blocks light.
//!
//! Cost: the plain occlusion query runs first (packets in the wavefront integrator),
//! and only a ray it finds blocked, in a scene with a transmissive material, is traced
//! again with the filtered query ([`SceneAccel::filtered_hit`], single ray, any-hit
//! mode: an opaque surface ends it). Those re-traced rays are counted in
//! `RayCounts::transmitted_shadow`. Both integrators call [`transmittance`] on the
//! same rays, so they compute the same factors.
//!
//! Cut-outs (`integrator::texturing`) use the same second pass: a shadow ray blocked
//! in a scene with a cut-out material is traced again, and a candidate in a hole is
//! rejected without attenuation. That holds also with transmitted shadows off (glass
//! then blocks, holes still do not).

use crate::accel::{PrimRef, QueryOptions, SceneAccel};
use crate::geometry::Ray;
use crate::scene::Scene;
use glam::Vec3;

/// Whether shadow rays of this render need the second, filtered query: glass with
/// transmitted shadows `enabled`, or any cut-out material.
pub fn transmits(scene: &Scene, enabled: bool) -> bool {
    (enabled && scene.materials.iter().any(|m| m.is_transmissive()))
        || super::texturing::has_cutouts(scene)
}

/// The fraction of light that reaches the end of `ray` through the scene: the product
/// of the `transmission` of every transmissive surface on the way (when `through_glass`,
/// the transmitted-shadows setting; else glass blocks), or zero when an opaque surface
/// (or a product of exactly zero) is met. Holes of cut-out materials let the ray
/// through unchanged.
pub fn transmittance(scene: &Scene, accel: &SceneAccel, ray: &Ray) -> Vec3 {
    filtered_transmittance(scene, accel, ray, true)
}

/// [`transmittance`] with glass passing light only when `through_glass` (the
/// transmitted-shadows setting): what a render with cut-outs needs even when
/// transmitted shadows are off.
pub fn filtered_transmittance(
    scene: &Scene,
    accel: &SceneAccel,
    ray: &Ray,
    through_glass: bool,
) -> Vec3 {
    let mut t = Vec3::ONE;
    let opts = QueryOptions {
        cull_back_faces: false,
        any: true,
    };
    let blocked = accel.filtered_hit(ray, opts, &mut |c| {
        let m = &scene.materials[material_of(scene, c.hit.prim) as usize];
        if m.has_cutout() && super::texturing::is_hole(scene, ray, &c.hit) {
            return false;
        }
        if !(through_glass && m.is_transmissive()) {
            return true;
        }
        t *= m.transmission;
        t == Vec3::ZERO
    });
    if blocked.is_some() { Vec3::ZERO } else { t }
}

/// The material index of a scene primitive.
pub fn material_of(scene: &Scene, prim: PrimRef) -> u32 {
    match prim {
        PrimRef::Triangle(t) => scene.mesh.material[t as usize],
        PrimRef::Sphere(s) => scene.spheres.material[s as usize],
        PrimRef::MovingTriangle(t) => scene.motion.mesh.material[t as usize],
        PrimRef::MovingSphere(s) => scene.motion.spheres.material[s as usize],
        PrimRef::Instance { instance, prim } => scene.instances.material(instance, prim),
        PrimRef::Plane(p) => scene.planes[p as usize].material,
    }
}
