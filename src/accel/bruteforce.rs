use super::filter::{FilterSink, HitFilter, QueryOptions};
use super::{Accel, AccelInfo, Primitives, TraversalCounts};
use crate::geometry::{Hit, Ray, RayQuery};

/// Tests every primitive: the reference every other structure is checked against.
pub struct BruteForce<P: Primitives> {
    prims: P,
}

impl<P: Primitives> BruteForce<P> {
    pub fn new(prims: P) -> Self {
        BruteForce { prims }
    }
}

impl<P: Primitives> Accel for BruteForce<P> {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        let mut best: Option<Hit> = None;
        let mut tmax = q.tmax;
        for i in 0..self.prims.count() {
            if let Some(h) = self.prims.intersect(i, &q, tmax) {
                tmax = h.t;
                best = Some(Hit {
                    t: h.t,
                    prim: i as u32,
                    u: h.u,
                    v: h.v,
                });
            }
        }
        best
    }

    fn any_hit(&self, ray: &Ray) -> bool {
        let Some(q) = RayQuery::new(ray) else {
            return false;
        };
        (0..self.prims.count()).any(|i| self.prims.intersect(i, &q, q.tmax).is_some())
    }

    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        let mut sink = FilterSink::new(&q, opts, filter);
        for i in 0..self.prims.count() {
            if sink.test(&self.prims, i, i as u32, &q) {
                break;
            }
        }
        sink.best
    }

    fn traversal_counts(&self, ray: &Ray) -> Option<TraversalCounts> {
        let n = if ray.is_valid() {
            self.prims.count() as u64
        } else {
            0
        };
        Some(TraversalCounts {
            nodes: (n > 0) as u64,
            prim_tests: n,
        })
    }

    fn info(&self) -> AccelInfo {
        AccelInfo {
            name: "bruteforce",
            primitives: self.prims.count(),
            memory_bytes: self.prims.memory_bytes(),
            leaves: 1,
            nodes: 1,
            sah_cost: self.prims.count() as f64,
            ..Default::default()
        }
    }
}
