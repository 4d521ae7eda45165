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
//! Cost: the plain occlusion query runs first (packets in the wavefront integrator)
//! and says which primitive set blocks the ray first ([`Occluder`]). A blocked ray,
//! in a scene with a transmissive material, is then settled by [`ShadowFilter`]:
//! blocked by a set whose primitives are all opaque, it is dark without more work;
//! else it is traced again with the filtered query from that set on
//! ([`SceneAccel::filtered_hit_from`], single ray, any-hit mode: an opaque surface
//! ends it; the sets before it have no candidate, the occlusion query found none).
//! Those re-traced rays are counted in `RayCounts::transmitted_shadow`. Both
//! integrators call [`ShadowFilter::transmittance`] on the same rays, so they compute
//! the same factors and count the same re-traced rays.
//!
//! Measured (whitted_area64 at 256x192, 1 thread): before the set was known, every
//! blocked ray was traced again from scratch, and the filtered query's scalar triangle
//! tests of the floor (which the floor's shadow rays start on) were 13 % of the frame.
//!
//! Cut-outs (`integrator::texturing`) use the same second pass: a shadow ray blocked
//! in a scene with a cut-out material is traced again, and a candidate in a hole is
//! rejected without attenuation. That holds also with transmitted shadows off (glass
//! then blocks, holes still do not).

use crate::accel::{Occluder, PrimRef, QueryOptions, SceneAccel};
use crate::geometry::Ray;
use crate::scene::Scene;
use crate::stats::RayCounts;
use glam::Vec3;

/// Whether shadow rays of this render need the second, filtered query: glass with
/// transmitted shadows `enabled`, or any cut-out material.
pub fn transmits(scene: &Scene, enabled: bool) -> bool {
    (enabled && scene.materials.iter().any(|m| m.is_transmissive()))
        || super::texturing::has_cutouts(scene)
}

/// What a render needs to settle its blocked shadow rays: the transmitted-shadows
/// setting and which primitive sets are opaque throughout. Built once per render
/// ([`ShadowFilter::new`] scans the material of every primitive).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShadowFilter {
    through_glass: bool,
    /// Per [`Occluder`] (in `Occluder::ALL` order): every primitive of the set blocks
    /// light (no glass passing it, no cut-out). Instances and planes count as not
    /// opaque (always traced again).
    opaque: [bool; 4],
}

impl ShadowFilter {
    /// `None` when the render's shadow rays need no second query ([`transmits`]).
    pub fn new(scene: &Scene, through_glass: bool) -> Option<ShadowFilter> {
        if !transmits(scene, through_glass) {
            return None;
        }
        let passes: Vec<bool> = scene
            .materials
            .iter()
            .map(|m| (through_glass && m.is_transmissive()) || m.has_cutout())
            .collect();
        let opaque = |ids: &[u32]| ids.iter().all(|&m| !passes[m as usize]);
        let motion = &scene.motion;
        Some(ShadowFilter {
            through_glass,
            opaque: [
                opaque(&scene.mesh.material),
                opaque(&scene.spheres.material),
                opaque(&motion.mesh.material) && opaque(&motion.spheres.material),
                false,
            ],
        })
    }

    /// Whether every primitive of `set` blocks light.
    pub fn is_opaque(&self, set: Occluder) -> bool {
        self.opaque[set as usize]
    }

    /// The transmittance of `ray`, which the occlusion query found blocked first by
    /// `first`: zero for an opaque set, else [`filtered_transmittance`] from `first`
    /// on (counted in `rays.transmitted_shadow`). The same as
    /// [`filtered_transmittance`] of the whole scene, as long as the occlusion and the
    /// filtered queries agree on which primitives the ray meets.
    pub fn transmittance(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        ray: &Ray,
        first: Occluder,
        rays: &mut RayCounts,
    ) -> Vec3 {
        if self.is_opaque(first) {
            return Vec3::ZERO;
        }
        rays.transmitted_shadow += 1;
        filtered_transmittance_from(scene, accel, ray, self.through_glass, first)
    }
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
    filtered_transmittance_from(scene, accel, ray, through_glass, Occluder::Triangles)
}

/// [`filtered_transmittance`] over the primitive sets from `from` on
/// ([`SceneAccel::filtered_hit_from`]).
pub fn filtered_transmittance_from(
    scene: &Scene,
    accel: &SceneAccel,
    ray: &Ray,
    through_glass: bool,
    from: Occluder,
) -> Vec3 {
    let mut t = Vec3::ONE;
    let opts = QueryOptions {
        cull_back_faces: false,
        any: true,
    };
    let blocked = accel.filtered_hit_from(
        ray,
        opts,
        &mut |c| {
            let m = &scene.materials[material_of(scene, c.hit.prim) as usize];
            if m.has_cutout() && super::texturing::is_hole(scene, ray, &c.hit) {
                return false;
            }
            if !(through_glass && m.is_transmissive()) {
                return true;
            }
            t *= m.transmission;
            t == Vec3::ZERO
        },
        from,
    );
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
