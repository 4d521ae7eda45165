//! The hits of a wave as a structure of arrays, grouped by material ([`HitBatch`]):
//! what the shading stage reads, 16 hits to a lane load.
//!
//! A counting sort on the material index (one pass to count, one to place, queue order
//! kept within a material) puts the hits of one material next to each other, so a lane
//! group shares one shading model and its constants (Laine, Karras and Aila, HPG 2013,
//! sort the queue by material for the same reason). Each hit's surface interaction
//! ([`SurfaceInteraction::new`]) is then written, in that order, component by component:
//! hit point, error bound, geometric and shading normals, shadow-ray base point, the
//! smooth-mesh flag as a lane mask, side, uv and the unit ray direction.

use super::interaction::SurfaceInteraction;
use super::shadow::material_of;
use crate::accel::SceneHit;
use crate::geometry::Ray;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use std::ops::Range;

/// Lanes of one load: every array is padded by this many entries past the last hit, so
/// a 16-lane load at any hit stays in bounds.
pub const LANES: usize = 16;

/// Three f32 arrays, one per component.
#[derive(Default)]
pub(crate) struct Soa3 {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
}

impl Soa3 {
    fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.z.clear();
    }

    fn push(&mut self, v: Vec3) {
        self.x.push(v.x);
        self.y.push(v.y);
        self.z.push(v.z);
    }

    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// The 16 lanes starting at hit `i`.
    pub fn lanes(&self, i: usize) -> crate::simd::lanes3::V3 {
        crate::simd::lanes3::V3::load(&self.x[i..], &self.y[i..], &self.z[i..])
    }
}

/// The hits of one wave, structure of arrays, grouped by material.
#[derive(Default)]
pub(crate) struct HitBatch {
    /// Queue index of each hit.
    pub ray: Vec<u32>,
    /// Runs of one material: `(material, hits)`, in material order.
    pub groups: Vec<(u32, Range<usize>)>,
    pub p: Soa3,
    pub p_error: Soa3,
    pub ng: Soa3,
    pub ns: Soa3,
    /// `p_shadow` where the hit has one (smooth meshes), else `p`.
    pub base: Soa3,
    /// All-ones bits where the hit has a `p_shadow`, zero elsewhere (a lane mask).
    pub smooth: Vec<f32>,
    /// Lane mask: the ray hit the outside (`front_face`).
    pub front: Vec<f32>,
    pub uv: Vec<Vec2>,
    /// Unit direction of the ray (`ray.dir.normalize()`, what the shader is given).
    pub dir: Soa3,
    /// Scratch of the sort: material of each queue entry, count per material.
    material: Vec<u32>,
    count: Vec<u32>,
}

const MASK_SET: f32 = f32::from_bits(u32::MAX);

impl HitBatch {
    /// The batch's `Vec3` columns, for what is done to each alike.
    fn vec3_columns(&mut self) -> [&mut Soa3; 6] {
        [
            &mut self.p,
            &mut self.p_error,
            &mut self.ng,
            &mut self.ns,
            &mut self.base,
            &mut self.dir,
        ]
    }

    /// Hits in the batch.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.ray.len()
    }

    /// Rebuilds the batch from the rays of a queue and their hits (misses are left out).
    pub fn build(&mut self, scene: &Scene, rays: &[Ray], hits: &[Option<SceneHit>]) {
        // Counting sort on the material index.
        self.material.clear();
        self.count.clear();
        self.count.resize(scene.materials.len() + 1, 0);
        for hit in hits {
            let m = hit.map_or(u32::MAX, |h| material_of(scene, h.prim));
            self.material.push(m);
            if m != u32::MAX {
                self.count[m as usize + 1] += 1;
            }
        }
        self.groups.clear();
        let mut start = 0;
        for m in 0..scene.materials.len() {
            let n = self.count[m + 1] as usize;
            // Prefix sum: count[m] becomes the first slot of material m.
            self.count[m] = start as u32;
            if n > 0 {
                self.groups.push((m as u32, start..start + n));
            }
            start += n;
        }
        self.ray.clear();
        self.ray.resize(start, 0);
        for (i, &m) in self.material.iter().enumerate() {
            if m != u32::MAX {
                let at = &mut self.count[m as usize];
                self.ray[*at as usize] = i as u32;
                *at += 1;
            }
        }
        for a in self.vec3_columns() {
            a.clear();
        }
        self.smooth.clear();
        self.front.clear();
        self.uv.clear();
        for k in 0..self.ray.len() {
            let i = self.ray[k] as usize;
            let ray = &rays[i];
            let hit = hits[i].as_ref().expect("sorted entries are hits");
            let si = SurfaceInteraction::new(scene, ray, hit);
            debug_assert_eq!(si.material, self.material[i]);
            self.p.push(si.p);
            self.p_error.push(si.p_error);
            self.ng.push(si.n_geometric);
            self.ns.push(si.n_shading);
            self.base.push(si.p_shadow.unwrap_or(si.p));
            self.smooth
                .push(if si.p_shadow.is_some() { MASK_SET } else { 0.0 });
            self.front.push(if si.front_face { MASK_SET } else { 0.0 });
            self.uv.push(si.uv);
            self.dir.push(ray.dir.normalize());
        }
        // Padding for the last lane load.
        for a in self.vec3_columns() {
            for _ in 0..LANES {
                a.push(Vec3::ZERO);
            }
        }
        self.smooth.extend([0.0; LANES]);
        self.front.extend([0.0; LANES]);
    }

    /// The surface interaction of hit `k` (of material `material`), as
    /// [`SurfaceInteraction::new`] built it.
    pub fn interaction(&self, k: usize, material: u32) -> SurfaceInteraction {
        let p = self.p.get(k);
        SurfaceInteraction {
            p,
            p_error: self.p_error.get(k),
            n_geometric: self.ng.get(k),
            n_shading: self.ns.get(k),
            material,
            front_face: self.front[k].to_bits() != 0,
            p_shadow: (self.smooth[k].to_bits() != 0).then(|| self.base.get(k)),
            uv: self.uv[k],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{AccelKind, SceneAccel};
    use crate::scene::load::load_scene;

    /// The batch holds every hit once, grouped by material in queue order within a
    /// group, and gives back exactly the interaction `SurfaceInteraction::new` builds.
    #[test]
    fn batch_is_a_material_sorted_copy_of_the_interactions() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/whitted.toml");
        let scene = load_scene(&path).expect("whitted.toml loads");
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let frame = scene.camera.frame(40, 30);
        let rays: Vec<Ray> = (0..30)
            .flat_map(|y| (0..40).map(move |x| (x, y)))
            .map(|(x, y)| frame.ray(x as f32 + 0.5, y as f32 + 0.5))
            .collect();
        let hits: Vec<_> = rays.iter().map(|r| accel.closest_hit(r)).collect();
        let mut batch = HitBatch::default();
        batch.build(&scene, &rays, &hits);
        let n_hits = hits.iter().filter(|h| h.is_some()).count();
        assert_eq!(batch.len(), n_hits);
        assert!(
            batch.groups.len() >= 2,
            "whitted has several materials in view"
        );
        let mut seen = vec![false; rays.len()];
        let mut covered = 0;
        let mut last_material = None;
        for (m, range) in &batch.groups {
            assert!(last_material < Some(*m), "groups in material order");
            last_material = Some(*m);
            assert_eq!(range.start, covered);
            covered = range.end;
            let idx = &batch.ray[range.clone()];
            assert!(idx.windows(2).all(|w| w[0] < w[1]), "queue order kept");
            for (k, &i) in range.clone().zip(idx) {
                let i = i as usize;
                assert!(!seen[i]);
                seen[i] = true;
                let want = SurfaceInteraction::new(&scene, &rays[i], hits[i].as_ref().unwrap());
                assert_eq!(batch.interaction(k, *m), want);
                assert_eq!(batch.dir.get(k), rays[i].dir.normalize());
            }
        }
        assert_eq!(covered, n_hits);
        assert!(batch.p.x.len() >= n_hits + LANES);
    }
}
