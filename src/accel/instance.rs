//! Two-level acceleration for instanced geometry: one bottom-level structure (BLAS)
//! per object, built once by the scene's [`AccelKind`] (so BVH4/BVH8 BLASes run the
//! same SIMD kernels as the flat mesh), and a top-level BVH over the instances' world
//! boxes (Wald, Benthin, Slusallek, "A Simple and Practical Method for Interactive Ray
//! Tracing of Dynamic Scenes", 2003; Embree's and pbrt's `TransformedPrimitive`).
//!
//! A ray reaching an instance's leaf is mapped into object space with the instance's
//! inverse transform, origin and direction alike, the direction *not* normalised, so
//! the ray's parameter `t` is the same in both spaces and one interval `(tmin, tmax)`
//! (the nearest hit so far) serves every instance and the rest of the scene. Hits carry
//! the instance index next to the object's triangle index; the world-space surface is
//! rebuilt from them ([`crate::scene::InstanceSet::surface`], with its error bound).
//!
//! Memory: `k` instances of an object cost one BLAS plus, per instance, two 3x4
//! matrices, one top-level leaf reference and about one top-level node
//! ([`InstanceAccel::top_memory_bytes`]).

use super::{Accel, AccelInfo, AccelKind, Candidate, HitFilter, QueryOptions, Triangles};
use crate::geometry::{Aabb, Hit, Ray};
use crate::scene::{Affine, InstanceSet};

/// One node of the top-level BVH: a leaf holds `count > 0` instances,
/// `order[start..start + count]`; an interior node (`count == 0`) has its children at
/// `start` and `start + 1`.
#[derive(Clone, Copy, Debug)]
struct TopNode {
    bounds: Aabb,
    start: u32,
    count: u32,
}

/// Instances per top-level leaf at most.
const TOP_LEAF: usize = 2;

/// The two-level structure over a scene's instances.
pub struct InstanceAccel {
    /// One structure per object; `None` for an object no instance uses (or an empty one).
    blas: Vec<Option<Box<dyn Accel>>>,
    /// Per instance: its object and world-to-object map.
    object: Vec<u32>,
    to_object: Vec<Affine>,
    nodes: Vec<TopNode>,
    /// Instance indices in leaf order.
    order: Vec<u32>,
    depth: usize,
    build_ms: f64,
}

impl InstanceAccel {
    /// `None` for a scene without instances.
    pub fn build(set: &InstanceSet, kind: AccelKind) -> Option<InstanceAccel> {
        if set.is_empty() {
            return None;
        }
        let start = std::time::Instant::now();
        let used: Vec<bool> = (0..set.objects.len())
            .map(|o| set.instances.iter().any(|i| i.object as usize == o))
            .collect();
        let blas = set
            .objects
            .iter()
            .zip(&used)
            .map(|(mesh, &used)| {
                (used && !mesh.is_empty()).then(|| kind.build(Triangles::from_mesh(mesh)))
            })
            .collect();
        let boxes = set.world_bounds();
        let mut order: Vec<u32> = (0..set.instances.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let mut nodes = Vec::new();
        let mut depth = 0;
        if !order.is_empty() {
            nodes.push(TopNode {
                bounds: Aabb::EMPTY,
                start: 0,
                count: 0,
            });
            build_node(&boxes, &mut order, 0, &mut nodes, 0, 1, &mut depth);
        }
        Some(InstanceAccel {
            blas,
            object: set.instances.iter().map(|i| i.object).collect(),
            to_object: set.instances.iter().map(|i| i.to_object).collect(),
            nodes,
            order,
            depth,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// The ray in instance `inst`'s object space, same interval and time.
    #[inline]
    fn object_ray(&self, inst: u32, ray: &Ray) -> Ray {
        let m = &self.to_object[inst as usize];
        Ray {
            origin: m.point(ray.origin),
            dir: m.vector(ray.dir),
            ..*ray
        }
    }

    #[inline]
    fn blas(&self, inst: u32) -> Option<&dyn Accel> {
        self.blas[self.object[inst as usize] as usize].as_deref()
    }

    /// Walks the top-level BVH nearest child first, calling `visit` for each instance
    /// whose world box the ray enters before `tmax`; `visit` returns the new `tmax`
    /// (the nearest hit so far) and whether to stop.
    fn traverse(&self, ray: &Ray, visit: &mut dyn FnMut(u32, f32) -> (f32, bool)) {
        if self.nodes.is_empty() || !ray.is_valid() {
            return;
        }
        let inv = glam::Vec3::ONE / ray.dir;
        let mut tmax = ray.tmax;
        let mut stack = [0u32; 64];
        let mut sp = 0;
        let mut node = 0u32;
        if self.nodes[0]
            .bounds
            .intersect(ray.origin, inv, ray.tmin, tmax)
            .is_none()
        {
            return;
        }
        loop {
            let n = &self.nodes[node as usize];
            if n.count > 0 {
                for &inst in &self.order[n.start as usize..(n.start + n.count) as usize] {
                    let (t, stop) = visit(inst, tmax);
                    tmax = t;
                    if stop {
                        return;
                    }
                }
            } else {
                let (a, b) = (n.start, n.start + 1);
                let ta = self.nodes[a as usize]
                    .bounds
                    .intersect(ray.origin, inv, ray.tmin, tmax);
                let tb = self.nodes[b as usize]
                    .bounds
                    .intersect(ray.origin, inv, ray.tmin, tmax);
                match (ta, tb) {
                    (Some(x), Some(y)) => {
                        let (near, far) = if x <= y { (a, b) } else { (b, a) };
                        stack[sp] = far;
                        sp += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node that the ray still enters before the nearest hit.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                node = stack[sp];
                if self.nodes[node as usize]
                    .bounds
                    .intersect(ray.origin, inv, ray.tmin, tmax)
                    .is_some()
                {
                    break;
                }
            }
        }
    }

    /// The nearest hit as `(instance, hit)`; `hit.prim` is the triangle of the
    /// instance's object.
    pub fn closest_hit(&self, ray: &Ray) -> Option<(u32, Hit)> {
        let mut best = None;
        self.traverse(ray, &mut |inst, tmax| {
            if let Some(blas) = self.blas(inst) {
                let mut r = self.object_ray(inst, ray);
                r.tmax = tmax;
                if let Some(h) = blas.closest_hit(&r) {
                    best = Some((inst, h));
                    return (h.t, false);
                }
            }
            (tmax, false)
        });
        best
    }

    /// Whether anything blocks the ray.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        let mut blocked = false;
        self.traverse(ray, &mut |inst, tmax| {
            blocked = self
                .blas(inst)
                .is_some_and(|b| b.any_hit(&self.object_ray(inst, ray)));
            (tmax, blocked)
        });
        blocked
    }

    /// The filtered query ([`Accel::filtered_hit`]) over every instance; `filter` also
    /// receives the instance index. Returns `(instance, hit)`.
    pub fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut dyn FnMut(u32, &Candidate) -> bool,
    ) -> Option<(u32, Hit)> {
        let mut best = None;
        self.traverse(ray, &mut |inst, tmax| {
            let Some(blas) = self.blas(inst) else {
                return (tmax, false);
            };
            let mut r = self.object_ray(inst, ray);
            r.tmax = tmax;
            let f: &mut HitFilter<'_> = &mut |c: &Candidate| filter(inst, c);
            match blas.filtered_hit(&r, opts, f) {
                Some(h) => {
                    best = Some((inst, h));
                    (h.t, opts.any)
                }
                None => (tmax, false),
            }
        });
        best
    }

    /// Bytes of the bottom-level structures (one per object used).
    pub fn blas_memory_bytes(&self) -> usize {
        self.blas
            .iter()
            .flatten()
            .map(|b| b.info().memory_bytes)
            .sum()
    }

    /// Bytes of the top level: nodes, leaf order, and per instance its object index
    /// and inverse transform.
    pub fn top_memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<TopNode>()
            + self.order.len() * 4
            + self.object.len() * 4
            + self.to_object.len() * std::mem::size_of::<Affine>()
    }

    /// Instances placed.
    pub fn instance_count(&self) -> usize {
        self.object.len()
    }

    /// One entry for the whole two-level structure: `primitives` counts instances,
    /// nodes, leaves and memory add both levels (each BLAS once), depth is the top
    /// level's plus the deepest BLAS.
    pub fn info(&self) -> AccelInfo {
        let blas: Vec<AccelInfo> = self.blas.iter().flatten().map(|b| b.info()).collect();
        let top_leaves = self.nodes.iter().filter(|n| n.count > 0).count();
        AccelInfo {
            name: "instances",
            primitives: self.instance_count(),
            build_ms: self.build_ms,
            nodes: self.nodes.len() + blas.iter().map(|b| b.nodes).sum::<usize>(),
            leaves: top_leaves + blas.iter().map(|b| b.leaves).sum::<usize>(),
            max_depth: self.depth + blas.iter().map(|b| b.max_depth).max().unwrap_or(0),
            memory_bytes: self.top_memory_bytes() + self.blas_memory_bytes(),
            sah_cost: 0.0,
        }
    }
}

/// Builds node `index` over `order[lo..]` (`order` is the slice for this node, starting
/// at `lo` in the whole array): median split on the largest axis of the centroids.
fn build_node(
    boxes: &[Aabb],
    order: &mut [u32],
    lo: usize,
    nodes: &mut Vec<TopNode>,
    index: usize,
    level: usize,
    depth: &mut usize,
) {
    *depth = (*depth).max(level);
    let bounds = order
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(&boxes[i as usize]));
    if order.len() <= TOP_LEAF {
        nodes[index] = TopNode {
            bounds,
            start: lo as u32,
            count: order.len() as u32,
        };
        return;
    }
    let mut centroids = Aabb::EMPTY;
    for &i in order.iter() {
        centroids.grow(boxes[i as usize].center());
    }
    let axis = centroids.largest_axis();
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        boxes[a as usize].center()[axis].total_cmp(&boxes[b as usize].center()[axis])
    });
    let left = nodes.len();
    let empty = TopNode {
        bounds: Aabb::EMPTY,
        start: 0,
        count: 0,
    };
    nodes.push(empty);
    nodes.push(empty);
    nodes[index] = TopNode {
        bounds,
        start: left as u32,
        count: 0,
    };
    let (a, b) = order.split_at_mut(mid);
    build_node(boxes, a, lo, nodes, left, level + 1, depth);
    build_node(boxes, b, lo + mid, nodes, left + 1, level + 1, depth);
}
