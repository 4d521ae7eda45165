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
//! A set that mixes opaque primitives with glass (the Whitted room's mirror and glass
//! spheres) is split in two structures once per render ([`ShadowFilter::new`]): a ray
//! it blocks meets the opaque part first (an occlusion query, in packets in the
//! wavefront: [`ShadowFilter::transmittance_batch`]), and only a ray that part does
//! not block goes through the filtered query, over the glass part and the later sets.
//!
//! Measured (whitted_area64, /work/shared/anchors/povray/scenes, 1 thread, perf):
//! before the set was known, every blocked ray was traced again from scratch, and the
//! filtered query's scalar triangle tests of the floor (which the floor's shadow rays
//! start on) were 13 % of the frame at 256x192. Render phase at 256x192, 5 runs
//! interleaved with the previous binary on a machine loaded 9-11 on 2 cores (so only
//! the ratio means anything): median 5441 -> 3498 ms, the area-shadow stage 4123 ->
//! 2252 ms, pairwise ratios 1.31-2.58 (image byte-identical). The filtered query
//! over the glass part was then still single-ray (`sphere_candidates` and
//! `filtered_hit` ~14 % of the frame).
//!
//! Glass spheres in lanes: where the passing part of the sphere set is glass spheres
//! of one transmission colour (the Whitted rows), the wavefront settles its rays 16 at
//! a time ([`crate::simd::glass_shadow`]): the opaque part's spheres (when at most
//! [`TINY_MAX_PRIMITIVES`]) as an any-hit test, then the number of glass surfaces
//! crossed in the interval, which is the number of candidates the filtered query
//! would offer; the factor is `transmission` multiplied in that many times, which
//! with equal factors is the filtered query's product bit for bit, whatever order it
//! offers them in. The sets after the spheres (moving geometry, instances, planes),
//! when present, still go through the filtered query ray by ray. Measured: see
//! `GlassSpheres`.
//!
//! Cut-outs (`integrator::texturing`) use the same second pass: a shadow ray blocked
//! in a scene with a cut-out material is traced again, and a candidate in a hole is
//! rejected without attenuation. That holds also with transmitted shadows off (glass
//! then blocks, holes still do not).

use crate::accel::{
    Accel, AccelKind, Occluder, PrimRef, QueryOptions, SceneAccel, SceneHit, Spheres,
    TINY_MAX_PRIMITIVES, Triangles,
};
use crate::geometry::Ray;
use crate::scene::{Scene, SphereSet};
use crate::simd::PACKET_WIDTH;
use crate::simd::glass_shadow::{crossing_counts, settle_lanes};
use crate::stats::RayCounts;
use glam::Vec3;

/// Whether shadow rays of this render need the second, filtered query: glass with
/// transmitted shadows `enabled`, or any cut-out material.
pub fn transmits(scene: &Scene, enabled: bool) -> bool {
    (enabled && scene.materials.iter().any(|m| m.is_transmissive()))
        || super::texturing::has_cutouts(scene)
}

/// What a render needs to settle its blocked shadow rays: the transmitted-shadows
/// setting, which primitive sets are opaque throughout, and for the triangle and
/// sphere sets that mix opaque primitives with ones that pass light (a mirror and a
/// glass sphere), the set split in two structures of the render's kind. Built once
/// per render ([`ShadowFilter::new`] scans the material of every primitive).
pub struct ShadowFilter {
    through_glass: bool,
    /// Per [`Occluder`] (in `Occluder::ALL` order): every primitive of the set blocks
    /// light (no glass passing it, no cut-out). Instances and planes count as not
    /// opaque (always traced again).
    opaque: [bool; 4],
    /// The triangle and the sphere set, split where mixed.
    split: [Option<SplitSet>; 2],
    /// The passing part of a split sphere set when every sphere of it is glass of one
    /// `transmission` (no cut-outs): its rays are settled in lanes
    /// ([`crate::simd::glass_shadow`]).
    glass: Option<GlassSpheres>,
}

/// Glass spheres of one transmission colour. A ray crossing their surfaces `n` times in
/// its interval has the transmittance `transmission` multiplied in `n` times, whatever
/// the order the filtered query would offer the crossings in (all factors are equal),
/// so counting the crossings in lanes gives the filtered query's factor bit for bit.
///
/// With at most [`TINY_MAX_PRIMITIVES`] spheres in the set's opaque part, that part is
/// tested in the same lanes (`opaque`), instead of by its structure's packets.
///
/// Measured with the tiny-scene batch queries (`accel/tiny.rs`) in the same change,
/// against the previous binary, 5 runs interleaved, 1 thread, AVX2, load 4-5 on 2
/// cores, min/median/max ms, images byte-identical: whitted_area64 at 512x384 render
/// 2625/2949/3139 -> 1638/1719/2020, area-shadow stage 1932/2109/2258 ->
/// 903/1000/1210; whitted_base render 616/834/885 -> 584/637/713, shadow stage
/// 189/270/281 -> 91/120/148. perf (area64 at 256x192, self time): before, the
/// filtered query over the glass part (`sphere_candidates`, `filtered_hit`) was ~14 %
/// of the frame and the opaque part's `packet_any` ~5 %; after, `settle_lanes` is
/// 2.5 % and `transmittance_batch` around it 5 %.
struct GlassSpheres {
    spheres: Vec<(Vec3, f32)>,
    transmission: Vec3,
    opaque: Option<Vec<(Vec3, f32)>>,
}

/// A mixed primitive set split by what its primitives do to a shadow ray. A ray that
/// the set blocks is dark if the opaque part blocks it (one occlusion query, in
/// packets in the wavefront), else only the passing part can have candidates, and the
/// filtered query runs over that part alone.
struct SplitSet {
    opaque: Box<dyn Accel>,
    passing: Box<dyn Accel>,
    /// The index in the scene's set of each primitive of `passing`.
    passing_ids: Vec<u32>,
}

/// Reusable buffers of [`ShadowFilter::transmittance_batch`].
#[derive(Default)]
pub struct ShadowScratch {
    rays: Vec<Ray>,
    index: Vec<u32>,
    blocked: Vec<bool>,
    /// Rays for the glass lanes and their indices in the batch.
    pending: Vec<Ray>,
    pending_index: Vec<u32>,
}

impl ShadowFilter {
    /// `None` when the render's shadow rays need no second query ([`transmits`]).
    /// `kind` is the structure the split sets are built with (the render's).
    pub fn new(scene: &Scene, through_glass: bool, kind: AccelKind) -> Option<ShadowFilter> {
        if !transmits(scene, through_glass) {
            return None;
        }
        let passes: Vec<bool> = scene
            .materials
            .iter()
            .map(|m| (through_glass && m.is_transmissive()) || m.has_cutout())
            .collect();
        let opaque = |ids: &[u32]| ids.iter().all(|&m| !passes[m as usize]);
        // The primitives of a set that pass light, when the set also has opaque ones.
        let mixed = |ids: &[u32]| -> Option<Vec<u32>> {
            let passing: Vec<u32> = (0..ids.len() as u32)
                .filter(|&i| passes[ids[i as usize] as usize])
                .collect();
            (!passing.is_empty() && passing.len() < ids.len()).then_some(passing)
        };
        let mesh = &scene.mesh;
        let triangles = mixed(&mesh.material).map(|passing| {
            let part = |keep: &dyn Fn(u32) -> bool| -> Box<dyn Accel> {
                let corners: Vec<_> = (0..mesh.len() as u32)
                    .filter(|&i| keep(i))
                    .map(|i| mesh.corners(i as usize))
                    .collect();
                kind.build(Triangles::from_corners(&corners))
            };
            let pass = |i: u32| passes[mesh.material[i as usize] as usize];
            SplitSet {
                opaque: part(&|i| !pass(i)),
                passing: part(&pass),
                passing_ids: passing,
            }
        });
        let set = &scene.spheres;
        let glass = mixed(&set.material).and_then(|passing| {
            let material = |i: u32| &scene.materials[set.material[i as usize] as usize];
            let transmission = material(passing[0]).transmission;
            passing
                .iter()
                .all(|&i| {
                    let m = material(i);
                    through_glass
                        && m.is_transmissive()
                        && !m.has_cutout()
                        && m.transmission == transmission
                })
                .then(|| {
                    let sphere = |i: u32| (set.center(i as usize), set.radius[i as usize]);
                    let opaque: Vec<_> = (0..set.len() as u32)
                        .filter(|i| !passing.contains(i))
                        .map(sphere)
                        .collect();
                    GlassSpheres {
                        spheres: passing.iter().map(|&i| sphere(i)).collect(),
                        transmission,
                        opaque: (opaque.len() <= TINY_MAX_PRIMITIVES).then_some(opaque),
                    }
                })
        });
        let spheres = mixed(&set.material).map(|passing| {
            let part = |keep: &dyn Fn(u32) -> bool| -> Box<dyn Accel> {
                let mut sub = SphereSet::default();
                for i in (0..set.len() as u32).filter(|&i| keep(i)) {
                    let i = i as usize;
                    sub.cx.push(set.cx[i]);
                    sub.cy.push(set.cy[i]);
                    sub.cz.push(set.cz[i]);
                    sub.radius.push(set.radius[i]);
                    sub.material.push(set.material[i]);
                }
                kind.build(Spheres::from_set(&sub))
            };
            let pass = |i: u32| passes[set.material[i as usize] as usize];
            SplitSet {
                opaque: part(&|i| !pass(i)),
                passing: part(&pass),
                passing_ids: passing,
            }
        });
        let motion = &scene.motion;
        Some(ShadowFilter {
            through_glass,
            opaque: [
                opaque(&scene.mesh.material),
                opaque(&scene.spheres.material),
                opaque(&motion.mesh.material) && opaque(&motion.spheres.material),
                false,
            ],
            split: [triangles, spheres],
            glass,
        })
    }

    /// The one-pass settlement of the shadow rays of a tiny scene
    /// ([`TinyShadow`](super::tiny_shadow::TinyShadow)), where `accel`'s batch queries
    /// go through its `TinyScene` alone, the triangles are all opaque, and the spheres
    /// all opaque or split with glass of one transmission in lanes; else `None`.
    pub fn tiny_pass<'a>(
        &'a self,
        accel: &'a SceneAccel,
    ) -> Option<super::tiny_shadow::TinyShadow<'a>> {
        use super::tiny_shadow::{SphereShadow, TinyShadow};
        let tiny = accel.tiny.as_ref()?;
        if accel.has_sets_from(Occluder::Moving)
            || !self.is_opaque(Occluder::Triangles)
            || self.is_split(Occluder::Triangles)
        {
            return None;
        }
        let spheres = if self.is_opaque(Occluder::Spheres) {
            SphereShadow::Opaque
        } else {
            let glass = self.glass.as_ref()?;
            SphereShadow::Glass {
                opaque: glass.opaque.as_deref()?,
                glass: &glass.spheres,
                transmission: glass.transmission,
            }
        };
        Some(TinyShadow { tiny, spheres })
    }

    /// Whether every primitive of `set` blocks light.
    pub fn is_opaque(&self, set: Occluder) -> bool {
        self.opaque[set as usize]
    }

    /// Whether `set` mixes opaque primitives with ones that pass light, and is split.
    pub fn is_split(&self, set: Occluder) -> bool {
        self.split_of(set).is_some()
    }

    fn split_of(&self, set: Occluder) -> Option<&SplitSet> {
        match set {
            Occluder::Triangles => self.split[0].as_ref(),
            Occluder::Spheres => self.split[1].as_ref(),
            _ => None,
        }
    }

    /// The transmittance of `ray`, which the occlusion query found blocked first by
    /// `first`: zero for an opaque set; for a split set zero if its opaque part blocks
    /// the ray, else the filtered query over its passing part and the sets after it;
    /// else [`filtered_transmittance`] from `first` on. Every ray but those of an
    /// opaque set is counted in `rays.transmitted_shadow`. The same as
    /// [`filtered_transmittance`] of the whole scene as long as the occlusion and the
    /// filtered queries agree on which primitives the ray meets, up to the order in
    /// which the transmissions of different materials are multiplied (the passing
    /// part's structure visits them in its own order).
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
        match self.split_of(first) {
            Some(split) if split.opaque.any_hit(ray) => Vec3::ZERO,
            Some(split) => self.through_passing(scene, accel, ray, first, split),
            None => filtered_transmittance_from(scene, accel, ray, self.through_glass, first),
        }
    }

    /// [`transmittance`](Self::transmittance) of every ray of `rays` into `out`: one
    /// for a ray that `first` says is unblocked. The rays blocked by a split set meet
    /// its opaque part in one occlusion batch (packets), the rest ray by ray, so the
    /// answers are [`transmittance`](Self::transmittance)'s.
    #[allow(clippy::too_many_arguments)]
    pub fn transmittance_batch(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        rays: &[Ray],
        first: &[Option<Occluder>],
        out: &mut Vec<Vec3>,
        scratch: &mut ShadowScratch,
        counts: &mut RayCounts,
    ) {
        out.clear();
        out.resize(rays.len(), Vec3::ONE);
        for (set, split) in [Occluder::Triangles, Occluder::Spheres]
            .into_iter()
            .filter_map(|s| self.split_of(s).map(|p| (s, p)))
        {
            scratch.index.clear();
            scratch.rays.clear();
            for (i, (r, f)) in rays.iter().zip(first).enumerate() {
                if *f == Some(set) {
                    scratch.index.push(i as u32);
                    scratch.rays.push(*r);
                }
            }
            if scratch.rays.is_empty() {
                continue;
            }
            counts.transmitted_shadow += scratch.rays.len() as u64;
            if let Some(glass) = self.glass.as_ref().filter(|_| set == Occluder::Spheres)
                && let Some(opaque) = &glass.opaque
            {
                // Opaque part and glass in one pass of lanes.
                let later = accel.has_sets_from(Occluder::Moving);
                for (rays, ids) in scratch
                    .rays
                    .chunks(PACKET_WIDTH)
                    .zip(scratch.index.chunks(PACKET_WIDTH))
                {
                    let (blocked, n) = settle_lanes(rays, opaque, &glass.spheres);
                    for (k, (r, &i)) in rays.iter().zip(ids).enumerate() {
                        out[i as usize] = if blocked >> k & 1 == 1 {
                            Vec3::ZERO
                        } else {
                            self.glass_factor(scene, accel, glass, r, n[k], later)
                        };
                    }
                }
                continue;
            }
            scratch.blocked.clear();
            scratch.blocked.resize(scratch.rays.len(), false);
            split
                .opaque
                .any_hit_batch(&scratch.rays, &mut scratch.blocked);
            let glass = self.glass.as_ref().filter(|_| set == Occluder::Spheres);
            scratch.pending.clear();
            scratch.pending_index.clear();
            for ((&i, r), &b) in scratch
                .index
                .iter()
                .zip(&scratch.rays)
                .zip(&scratch.blocked)
            {
                if b {
                    out[i as usize] = Vec3::ZERO;
                } else if glass.is_some() {
                    scratch.pending.push(*r);
                    scratch.pending_index.push(i);
                } else {
                    out[i as usize] = self.through_passing(scene, accel, r, set, split);
                }
            }
            if let Some(glass) = glass {
                self.through_glass_lanes(scene, accel, glass, scratch, out);
            }
        }
        for ((o, r), f) in out.iter_mut().zip(rays).zip(first) {
            if let Some(set) = *f
                && !self.is_split(set)
            {
                *o = self.transmittance(scene, accel, r, set, counts);
            }
        }
    }

    /// [`through_passing`](Self::through_passing) of the sphere set for the rays of
    /// `scratch.pending` (into `out` at `scratch.pending_index`), the glass crossings
    /// counted in lanes.
    fn through_glass_lanes(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        glass: &GlassSpheres,
        scratch: &ShadowScratch,
        out: &mut [Vec3],
    ) {
        let later = accel.has_sets_from(Occluder::Moving);
        for (rays, ids) in scratch
            .pending
            .chunks(PACKET_WIDTH)
            .zip(scratch.pending_index.chunks(PACKET_WIDTH))
        {
            let counts = crossing_counts(rays, &glass.spheres);
            for ((r, &i), &n) in rays.iter().zip(ids).zip(&counts) {
                out[i as usize] = self.glass_factor(scene, accel, glass, r, n, later);
            }
        }
    }

    /// The transmittance of `ray` (not blocked by the sphere set's opaque part) that
    /// crosses the glass surfaces `crossings` times: `transmission` multiplied in that
    /// many times, then the sets after the spheres when there are any (`later`), as
    /// [`through_passing`](Self::through_passing) computes it.
    fn glass_factor(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        glass: &GlassSpheres,
        ray: &Ray,
        crossings: u32,
        later: bool,
    ) -> Vec3 {
        let mut t = Vec3::ONE;
        for _ in 0..crossings {
            t *= glass.transmission;
        }
        if t == Vec3::ZERO {
            Vec3::ZERO
        } else if later {
            transmittance_on(scene, accel, ray, self.through_glass, Occluder::Moving, t)
        } else {
            t
        }
    }

    /// The transmittance of `ray` through the passing part of the split set `set`
    /// (whose opaque part does not block it), then the sets after `set`.
    fn through_passing(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        ray: &Ray,
        set: Occluder,
        split: &SplitSet,
    ) -> Vec3 {
        let (prim, next): (fn(u32) -> PrimRef, _) = match set {
            Occluder::Triangles => (PrimRef::Triangle, Occluder::Spheres),
            _ => (PrimRef::Sphere, Occluder::Moving),
        };
        let mut t = Vec3::ONE;
        let opts = QueryOptions {
            cull_back_faces: false,
            any: true,
        };
        let blocked = split.passing.filtered_hit(ray, opts, &mut |c| {
            let hit = SceneHit {
                t: c.hit.t,
                prim: prim(split.passing_ids[c.hit.prim as usize]),
                u: c.hit.u,
                v: c.hit.v,
            };
            blocks(scene, ray, self.through_glass, &hit, &mut t)
        });
        if blocked.is_some() {
            return Vec3::ZERO;
        }
        transmittance_on(scene, accel, ray, self.through_glass, next, t)
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
    transmittance_on(scene, accel, ray, through_glass, from, Vec3::ONE)
}

/// `t` times the transmittance of `ray` over the sets from `from` on (the factors
/// multiplied into `t` one by one, as one query over all the sets would).
fn transmittance_on(
    scene: &Scene,
    accel: &SceneAccel,
    ray: &Ray,
    through_glass: bool,
    from: Occluder,
    mut t: Vec3,
) -> Vec3 {
    // Nothing from `from` on (the sets after a split one, often): `t` as it is. The
    // empty query cost 5 % of whitted_area64 (256x192) on the rays through glass.
    if !accel.has_sets_from(from) {
        return t;
    }
    let opts = QueryOptions {
        cull_back_faces: false,
        any: true,
    };
    let blocked = accel.filtered_hit_from(
        ray,
        opts,
        &mut |c| blocks(scene, ray, through_glass, &c.hit, &mut t),
        from,
    );
    if blocked.is_some() { Vec3::ZERO } else { t }
}

/// The filter of the transmittance queries: whether the candidate `hit` blocks the
/// ray (an opaque surface, or a product `t` that reached exactly zero); a candidate
/// that passes light multiplies `t` by its transmission, one in a hole passes it
/// unchanged.
fn blocks(scene: &Scene, ray: &Ray, through_glass: bool, hit: &SceneHit, t: &mut Vec3) -> bool {
    let m = &scene.materials[material_of(scene, hit.prim) as usize];
    if m.has_cutout() && super::texturing::is_hole(scene, ray, hit) {
        return false;
    }
    if !(through_glass && m.is_transmissive()) {
        return true;
    }
    *t *= m.transmission;
    *t == Vec3::ZERO
}

/// The material index of a scene primitive.
#[inline]
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
