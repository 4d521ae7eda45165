use crate::geometry::{Aabb, LaneRays, PrimHit, RayQuery, intersect_sphere, intersect_triangle};
use crate::scene::{SphereSet, TriangleMesh};
use crate::simd::Lanes;
use crate::simd::kernels::{RayLanes, sphere_lanes};
use glam::Vec3;

/// A set of primitives an acceleration structure can be built over.
///
/// Structures reorder primitives for locality with [`permute`](Primitives::permute)
/// and keep the original index to report in hits.
pub trait Primitives: Send + Sync + Sized {
    fn count(&self) -> usize;
    fn bounds(&self, i: usize) -> Aabb;
    /// Closest intersection of primitive `i` inside `(q.tmin, tmax)`.
    fn intersect(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<PrimHit>;
    /// Every intersection of primitive `i` inside `(q.tmin, tmax)`, nearest first, each
    /// with whether the ray meets the front face there: the candidates of a filtered
    /// query ([`super::filter`]). The nearest one is exactly what
    /// [`intersect`](Primitives::intersect) returns.
    fn intersect_each(&self, i: usize, q: &RayQuery, tmax: f32, f: &mut dyn FnMut(PrimHit, bool));
    /// The same set in a new order: element `k` of the result is element `order[k]` of `self`.
    fn permute(&self, order: &[u32]) -> Self;
    /// Bytes of primitive data held.
    fn memory_bytes(&self) -> usize;
    /// Whether primitive `i` may overlap box `b`: false only if it certainly does not.
    /// Spatial subdivisions use it to assign primitives to cells more tightly than by
    /// their bounds; the default answers with the bounds.
    fn overlaps_box(&self, i: usize, b: &Aabb) -> bool {
        let p = self.bounds(i);
        p.min.cmple(b.max).all() && b.min.cmple(p.max).all()
    }
    /// Primitive `i` against the lanes of a packet (`active` lanes only): the closest
    /// hit per lane in `(tmin, tmax)` as `(t, u, v, hit bits)`. The default runs the
    /// scalar test lane by lane; sets with a SIMD twin override it.
    fn intersect_lanes<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        i: usize,
        lanes: &RayLanes<L>,
        tmax: L,
        active: u32,
        rays: &R,
    ) -> (L, L, L, u32) {
        let _ = lanes;
        let tm = tmax.to_array();
        let (mut t, mut u, mut v) = (tm, L::splat(0.0).to_array(), L::splat(0.0).to_array());
        let mut bits = 0;
        for lane in (0..L::WIDTH).filter(|l| active >> l & 1 == 1) {
            let hit = rays
                .lane_query(lane)
                .and_then(|q| self.intersect(i, &q, tm.as_ref()[lane]));
            if let Some(h) = hit {
                (t.as_mut()[lane], u.as_mut()[lane], v.as_mut()[lane]) = (h.t, h.u, h.v);
                bits |= 1 << lane;
            }
        }
        (L::from_array(t), L::from_array(u), L::from_array(v), bits)
    }

    /// The set as triangles, for structures with packed SIMD triangle leaves.
    fn as_triangles(&self) -> Option<&Triangles> {
        None
    }
}

/// Triangles, de-indexed: three corner arrays, so a test reads one contiguous record
/// set with no index indirection.
#[derive(Clone, Debug, Default)]
pub struct Triangles {
    pub v0: Vec<Vec3>,
    pub v1: Vec<Vec3>,
    pub v2: Vec<Vec3>,
}

impl Triangles {
    pub fn from_mesh(mesh: &TriangleMesh) -> Self {
        let mut t = Triangles::default();
        for i in 0..mesh.len() {
            let [a, b, c] = mesh.corners(i);
            t.v0.push(a);
            t.v1.push(b);
            t.v2.push(c);
        }
        t
    }

    pub fn from_corners(corners: &[[Vec3; 3]]) -> Self {
        Triangles {
            v0: corners.iter().map(|c| c[0]).collect(),
            v1: corners.iter().map(|c| c[1]).collect(),
            v2: corners.iter().map(|c| c[2]).collect(),
        }
    }
}

impl Primitives for Triangles {
    fn count(&self) -> usize {
        self.v0.len()
    }

    fn bounds(&self, i: usize) -> Aabb {
        let mut b = Aabb::from_point(self.v0[i]);
        b.grow(self.v1[i]);
        b.grow(self.v2[i]);
        b
    }

    #[inline]
    fn intersect(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<PrimHit> {
        intersect_triangle(q, self.v0[i], self.v1[i], self.v2[i], tmax)
    }

    fn intersect_each(&self, i: usize, q: &RayQuery, tmax: f32, f: &mut dyn FnMut(PrimHit, bool)) {
        let corners = [self.v0[i], self.v1[i], self.v2[i]];
        super::filter::triangle_candidates(q, corners, tmax, f);
    }

    fn permute(&self, order: &[u32]) -> Self {
        Triangles {
            v0: order.iter().map(|&i| self.v0[i as usize]).collect(),
            v1: order.iter().map(|&i| self.v1[i as usize]).collect(),
            v2: order.iter().map(|&i| self.v2[i as usize]).collect(),
        }
    }

    fn memory_bytes(&self) -> usize {
        self.v0.len() * 36
    }

    fn as_triangles(&self) -> Option<&Triangles> {
        Some(self)
    }

    fn overlaps_box(&self, i: usize, b: &Aabb) -> bool {
        super::spatial::triangle_overlaps_box(self.v0[i], self.v1[i], self.v2[i], b)
    }
}

/// Spheres: centres and radii.
#[derive(Clone, Debug, Default)]
pub struct Spheres {
    pub center: Vec<Vec3>,
    pub radius: Vec<f32>,
}

impl Spheres {
    pub fn from_set(set: &SphereSet) -> Self {
        Spheres {
            center: (0..set.len()).map(|i| set.center(i)).collect(),
            radius: set.radius.clone(),
        }
    }
}

impl Primitives for Spheres {
    fn count(&self) -> usize {
        self.radius.len()
    }

    fn bounds(&self, i: usize) -> Aabb {
        let r = Vec3::splat(self.radius[i]);
        Aabb::new(self.center[i] - r, self.center[i] + r)
    }

    #[inline]
    fn intersect(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<PrimHit> {
        intersect_sphere(q, self.center[i], self.radius[i], tmax).map(|t| PrimHit {
            t,
            u: 0.0,
            v: 0.0,
        })
    }

    fn intersect_each(&self, i: usize, q: &RayQuery, tmax: f32, f: &mut dyn FnMut(PrimHit, bool)) {
        super::filter::sphere_candidates(q, self.center[i], self.radius[i], tmax, f);
    }

    #[inline]
    fn intersect_lanes<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        i: usize,
        lanes: &RayLanes<L>,
        tmax: L,
        active: u32,
        _rays: &R,
    ) -> (L, L, L, u32) {
        let (t, bits) = sphere_lanes(lanes, self.center[i], self.radius[i], tmax, active);
        let zero = L::splat(0.0);
        (t, zero, zero, bits)
    }

    fn permute(&self, order: &[u32]) -> Self {
        Spheres {
            center: order.iter().map(|&i| self.center[i as usize]).collect(),
            radius: order.iter().map(|&i| self.radius[i as usize]).collect(),
        }
    }

    fn memory_bytes(&self) -> usize {
        self.radius.len() * 16
    }

    fn overlaps_box(&self, i: usize, b: &Aabb) -> bool {
        super::spatial::sphere_overlaps_box(self.center[i], self.radius[i], b)
    }
}
