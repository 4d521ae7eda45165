//! The wavefront's queues: closest-hit rays (`RayQueue`) and shadow rays
//! (`ShadowQueue`) stored structure of arrays, and `PerChildKind`, the typed map
//! that holds one value (a queue, a flag) per kind of child ray.

use super::shader::ChildKind;
use crate::geometry::Ray;
use glam::Vec3;
use std::ops::{Index, IndexMut};

/// Closest-hit rays, structure of arrays. Every ray of a queue has the queue's kind and
/// the depth of the wave it belongs to, so neither is stored per ray. The geometric
/// part stays a [`Ray`] (origin, direction, t range, time) because that is what the
/// batch entry points of the structures consume.
#[derive(Default)]
pub(crate) struct RayQueue {
    pub rays: Vec<Ray>,
    /// Camera sample (accumulator) of the tile the ray contributes to.
    pub slot: Vec<u32>,
    /// Product of the weights from the camera: what the ray's radiance is scaled by.
    pub weight: Vec<Vec3>,
    /// Throughput for the contribution cutoff (see `ChildRay::throughput`).
    pub throughput: Vec<Vec3>,
    /// Path identity, which keys the random stream of the hit.
    pub path: Vec<u64>,
}

impl RayQueue {
    pub fn clear(&mut self) {
        self.rays.clear();
        self.slot.clear();
        self.weight.clear();
        self.throughput.clear();
        self.path.clear();
    }

    /// Appends camera rays: consecutive accumulator slots from `first_slot`, weight and
    /// throughput one, and path `first_path + (r + i) mod per_pixel` for ray `i` (`r`
    /// the position of the first ray in its pixel: camera rays are numbered within
    /// their pixel). When the queue is empty the rays are taken whole, without a copy
    /// (`rays` gets the queue's old buffer, emptied); else they are moved over.
    pub fn append_camera(
        &mut self,
        rays: &mut Vec<Ray>,
        first_slot: u32,
        (first_path, r, per_pixel): (u64, usize, usize),
    ) {
        let k = rays.len();
        if self.rays.is_empty() {
            std::mem::swap(&mut self.rays, rays);
            rays.clear();
        } else {
            self.rays.append(rays);
        }
        let n = self.rays.len();
        self.slot.extend(first_slot..first_slot + k as u32);
        self.weight.resize(n, Vec3::ONE);
        self.throughput.resize(n, Vec3::ONE);
        if per_pixel == 1 {
            self.path.resize(n, first_path);
        } else {
            // A counter that wraps, rather than a division per ray.
            let mut r = r % per_pixel;
            self.path.extend((0..k).map(|_| {
                let p = first_path + r as u64;
                r = if r + 1 == per_pixel { 0 } else { r + 1 };
                p
            }));
        }
    }

    pub fn push(&mut self, ray: Ray, slot: u32, weight: Vec3, throughput: Vec3, path: u64) {
        self.rays.push(ray);
        self.slot.push(slot);
        self.weight.push(weight);
        self.throughput.push(throughput);
        self.path.push(path);
    }
}

/// Any-hit rays with what each adds to its camera sample when unblocked.
#[derive(Default)]
pub(crate) struct ShadowQueue {
    pub rays: Vec<Ray>,
    pub slot: Vec<u32>,
    pub contribution: Vec<Vec3>,
}

impl ShadowQueue {
    pub fn clear(&mut self) {
        self.rays.clear();
        self.slot.clear();
        self.contribution.clear();
    }
}

/// One `T` per kind of child ray, indexed by [`ChildKind`]: a named field per kind
/// rather than an array indexed by enum discriminants.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct PerChildKind<T> {
    pub reflection: T,
    pub refraction: T,
    pub glossy: T,
    pub translucency: T,
}

impl<T> PerChildKind<T> {
    /// The map with `f` applied to every value.
    pub fn map<U>(self, mut f: impl FnMut(T) -> U) -> PerChildKind<U> {
        PerChildKind {
            reflection: f(self.reflection),
            refraction: f(self.refraction),
            glossy: f(self.glossy),
            translucency: f(self.translucency),
        }
    }

    /// Every kind with its value, in the order the wavefront traces its queues:
    /// reflection, refraction, glossy, translucency.
    pub fn iter(&self) -> impl Iterator<Item = (ChildKind, &T)> {
        [
            (ChildKind::Reflection, &self.reflection),
            (ChildKind::Refraction, &self.refraction),
            (ChildKind::Glossy, &self.glossy),
            (ChildKind::Translucency, &self.translucency),
        ]
        .into_iter()
    }
}

impl<T> Index<ChildKind> for PerChildKind<T> {
    type Output = T;
    fn index(&self, kind: ChildKind) -> &T {
        match kind {
            ChildKind::Reflection => &self.reflection,
            ChildKind::Refraction => &self.refraction,
            ChildKind::Glossy => &self.glossy,
            ChildKind::Translucency => &self.translucency,
        }
    }
}

impl<T> IndexMut<ChildKind> for PerChildKind<T> {
    fn index_mut(&mut self, kind: ChildKind) -> &mut T {
        match kind {
            ChildKind::Reflection => &mut self.reflection,
            ChildKind::Refraction => &mut self.refraction,
            ChildKind::Glossy => &mut self.glossy,
            ChildKind::Translucency => &mut self.translucency,
        }
    }
}

/// Test helper: one camera ray through the centre of each pixel of a `w x h` frame,
/// pixel `i` (row-major) in slot `i`, unit weight and throughput, all on path `path`.
#[cfg(test)]
impl RayQueue {
    pub(crate) fn pixel_centres(
        frame: &crate::scene::CameraFrame,
        w: u32,
        h: u32,
        path: u64,
    ) -> RayQueue {
        let mut queue = RayQueue::default();
        for i in 0..w * h {
            let ray = frame.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            queue.push(ray, i, Vec3::ONE, Vec3::ONE, path);
        }
        queue
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Indexing, iteration and `map` agree on which field belongs to which kind, and
    /// iteration follows the order the wavefront traces its queues.
    #[test]
    fn per_child_kind_is_keyed_by_kind() {
        const ALL: [ChildKind; 4] = ChildKind::ALL;
        let mut m = PerChildKind::<u32>::default();
        for (i, k) in ALL.into_iter().enumerate() {
            m[k] = 10 + i as u32;
        }
        assert_eq!(
            m,
            PerChildKind {
                reflection: 10,
                refraction: 11,
                glossy: 12,
                translucency: 13
            }
        );
        let kinds: Vec<_> = m.iter().map(|(k, &v)| (k, v)).collect();
        let expect: Vec<_> = ALL.into_iter().map(|k| (k, m[k])).collect();
        assert_eq!(kinds, expect);
        for k in ALL {
            m[k] += 1;
        }
        assert_eq!(
            m.map(|v| v * 2),
            PerChildKind {
                reflection: 22,
                refraction: 24,
                glossy: 26,
                translucency: 28
            }
        );
    }
}
