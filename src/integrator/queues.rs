//! The wavefront's queues: closest-hit rays ([`RayQueue`]) and shadow rays
//! ([`ShadowQueue`]) stored structure of arrays, and [`PerChildKind`], the typed map
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
    /// throughput one, and the given paths (one per ray).
    pub fn extend_camera(
        &mut self,
        rays: &[Ray],
        first_slot: u32,
        paths: impl ExactSizeIterator<Item = u64>,
    ) {
        debug_assert_eq!(rays.len(), paths.len());
        let n = self.rays.len() + rays.len();
        self.rays.extend_from_slice(rays);
        self.slot.extend(first_slot..first_slot + rays.len() as u32);
        self.weight.resize(n, Vec3::ONE);
        self.throughput.resize(n, Vec3::ONE);
        self.path.extend(paths);
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
