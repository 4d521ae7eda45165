//! Moving primitives for motion blur, in their own sets and their own structures, so
//! that the static sets, the BVH4 SIMD leaves and every static kernel stay untouched
//! (a scene without motion never builds or visits any of this).
//!
//! A moving primitive's bounds are the union of its bounds at shutter open and close,
//! which covers the whole linear motion; `intersect` places the primitive at the
//! ray's time (`RayQuery::time`).

use super::{Accel, AccelInfo, AccelKind, Bvh2, Primitives};
use crate::geometry::Hit;
use crate::geometry::{Aabb, PrimHit, Ray, RayQuery, intersect_sphere, intersect_triangle};
use crate::scene::MotionSet;
use glam::Vec3;

/// Spheres moving linearly: centre at time `t` is `center + t * velocity`.
#[derive(Clone, Debug, Default)]
pub struct MovingSpheres {
    pub center: Vec<Vec3>,
    pub velocity: Vec<Vec3>,
    pub radius: Vec<f32>,
    pub shutter: [f32; 2],
}

/// Triangles moving linearly: corners at time `t` are `v + t * velocity`.
#[derive(Clone, Debug, Default)]
pub struct MovingTriangles {
    pub v0: Vec<Vec3>,
    pub v1: Vec<Vec3>,
    pub v2: Vec<Vec3>,
    pub velocity: Vec<Vec3>,
    pub shutter: [f32; 2],
}

impl MovingSpheres {
    pub fn from_motion(m: &MotionSet, shutter: [f32; 2]) -> Self {
        MovingSpheres {
            center: (0..m.spheres.len()).map(|i| m.spheres.center(i)).collect(),
            velocity: m.sphere_velocity.clone(),
            radius: m.spheres.radius.clone(),
            shutter,
        }
    }
}

impl MovingTriangles {
    pub fn from_motion(m: &MotionSet, shutter: [f32; 2]) -> Self {
        let mut t = MovingTriangles {
            shutter,
            ..Default::default()
        };
        for i in 0..m.mesh.len() {
            let [a, b, c] = m.mesh.corners(i);
            t.v0.push(a);
            t.v1.push(b);
            t.v2.push(c);
        }
        t.velocity = m.triangle_velocity.clone();
        t
    }
}

impl Primitives for MovingSpheres {
    fn count(&self) -> usize {
        self.radius.len()
    }

    fn bounds(&self, i: usize) -> Aabb {
        let r = Vec3::splat(self.radius[i]);
        let mut b = Aabb::EMPTY;
        for t in self.shutter {
            let c = self.center[i] + t * self.velocity[i];
            b = b.union(&Aabb::new(c - r, c + r));
        }
        b
    }

    fn intersect(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<PrimHit> {
        let c = self.center[i] + q.time * self.velocity[i];
        intersect_sphere(q, c, self.radius[i], tmax).map(|t| PrimHit { t, u: 0.0, v: 0.0 })
    }

    fn intersect_each(&self, i: usize, q: &RayQuery, tmax: f32, f: &mut dyn FnMut(PrimHit, bool)) {
        let c = self.center[i] + q.time * self.velocity[i];
        super::filter::sphere_candidates(q, c, self.radius[i], tmax, f);
    }

    fn permute(&self, order: &[u32]) -> Self {
        let pick = |v: &Vec<Vec3>| order.iter().map(|&i| v[i as usize]).collect();
        MovingSpheres {
            center: pick(&self.center),
            velocity: pick(&self.velocity),
            radius: order.iter().map(|&i| self.radius[i as usize]).collect(),
            shutter: self.shutter,
        }
    }

    fn memory_bytes(&self) -> usize {
        self.radius.len() * 28
    }
}

impl Primitives for MovingTriangles {
    fn count(&self) -> usize {
        self.v0.len()
    }

    fn bounds(&self, i: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in self.shutter {
            let d = t * self.velocity[i];
            for v in [self.v0[i], self.v1[i], self.v2[i]] {
                b.grow(v + d);
            }
        }
        b
    }

    fn intersect(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<PrimHit> {
        let d = q.time * self.velocity[i];
        intersect_triangle(q, self.v0[i] + d, self.v1[i] + d, self.v2[i] + d, tmax)
    }

    fn intersect_each(&self, i: usize, q: &RayQuery, tmax: f32, f: &mut dyn FnMut(PrimHit, bool)) {
        let d = q.time * self.velocity[i];
        let corners = [self.v0[i] + d, self.v1[i] + d, self.v2[i] + d];
        super::filter::triangle_candidates(q, corners, tmax, f);
    }

    fn permute(&self, order: &[u32]) -> Self {
        let pick = |v: &Vec<Vec3>| order.iter().map(|&i| v[i as usize]).collect();
        MovingTriangles {
            v0: pick(&self.v0),
            v1: pick(&self.v1),
            v2: pick(&self.v2),
            velocity: pick(&self.velocity),
            shutter: self.shutter,
        }
    }

    fn memory_bytes(&self) -> usize {
        self.v0.len() * 48
    }
}

/// The structures over a scene's moving primitives: BVH2 (generic over
/// [`Primitives`]), or brute force when that is what the scene asked for.
pub struct MovingAccel {
    pub triangles: Option<Box<dyn Accel>>,
    pub spheres: Option<Box<dyn Accel>>,
}

impl MovingAccel {
    /// `None` for a scene without moving geometry.
    pub fn build(m: &MotionSet, shutter: [f32; 2], kind: AccelKind) -> Option<MovingAccel> {
        if m.is_empty() {
            return None;
        }
        fn build<P: Primitives + 'static>(p: P, kind: AccelKind) -> Box<dyn Accel> {
            match kind {
                AccelKind::BruteForce => kind.build(p),
                _ => Box::new(Bvh2::build(p)),
            }
        }
        Some(MovingAccel {
            triangles: (!m.mesh.is_empty())
                .then(|| build(MovingTriangles::from_motion(m, shutter), kind)),
            spheres: (!m.spheres.is_empty())
                .then(|| build(MovingSpheres::from_motion(m, shutter), kind)),
        })
    }

    pub fn closest_triangle(&self, ray: &Ray) -> Option<Hit> {
        self.triangles.as_ref().and_then(|a| a.closest_hit(ray))
    }

    pub fn closest_sphere(&self, ray: &Ray) -> Option<Hit> {
        self.spheres.as_ref().and_then(|a| a.closest_hit(ray))
    }

    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.triangles.as_ref().is_some_and(|a| a.any_hit(ray))
            || self.spheres.as_ref().is_some_and(|a| a.any_hit(ray))
    }

    pub fn info(&self) -> Vec<AccelInfo> {
        self.triangles
            .iter()
            .chain(self.spheres.iter())
            .map(|a| a.info())
            .collect()
    }
}
