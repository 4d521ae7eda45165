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
///
/// A queue of camera rays ([`append_camera`](RayQueue::append_camera)) stores only the
/// rays: its slots are consecutive, its weights and throughputs one and its paths
/// follow from each ray's place in its pixel, so [`CameraRun`] holds those as four
/// numbers and the accessors ([`slot`](RayQueue::slot), [`weight`](RayQueue::weight),
/// [`throughput`](RayQueue::throughput), [`path`](RayQueue::path)) hand them out on
/// demand; the per-ray arrays stay empty. So the arrays are private: a queue is read
/// through the accessors and written through [`push`](RayQueue::push),
/// [`extend`](RayQueue::extend) and [`append_camera`](RayQueue::append_camera), which
/// write a camera run out first where other rays join it.
///
/// Measured before (bunny 1024x1024, 1 ray per pixel): writing slot, weight,
/// throughput and path for every camera ray was 40 of the ~110 bytes the camera
/// stage wrote per ray.
#[derive(Default)]
pub(crate) struct RayQueue {
    pub rays: Vec<Ray>,
    /// Camera sample (accumulator) of the tile the ray contributes to.
    slot: Vec<u32>,
    /// Product of the weights from the camera: what the ray's radiance is scaled by.
    weight: Vec<Vec3>,
    /// Throughput for the contribution cutoff (see `ChildRay::throughput`).
    throughput: Vec<Vec3>,
    /// Path identity, which keys the random stream of the hit.
    path: Vec<u64>,
    /// `Some` while the queue holds only camera rays, whose per-ray values it implies.
    camera: Option<CameraRun>,
}

/// What a queue of camera rays implies for its ray `i`: slot `first_slot + i`, weight
/// and throughput one, path `first_path + (first_r + i) mod per_pixel`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct CameraRun {
    first_slot: u32,
    first_path: u64,
    /// Position in its pixel of the queue's first ray, below `per_pixel`.
    first_r: u32,
    per_pixel: u32,
}

impl CameraRun {
    #[inline]
    fn path(&self, i: usize) -> u64 {
        if self.per_pixel == 1 {
            self.first_path
        } else {
            self.first_path + ((self.first_r as u64 + i as u64) % self.per_pixel as u64)
        }
    }

    /// [`path`](CameraRun::path) of the rays `idx` (at most 16) into `out`, the
    /// remainder of each from the one before where their positions are less than
    /// `per_pixel` apart (ascending: a material group's hits in queue order), by an
    /// addition and at most one subtraction; a division only elsewhere.
    ///
    /// Before: a 64-bit division per ray of a mirror or glass lane group's camera
    /// hits (`path` above): the remainder's line held 1.3 % of `shade_group_lanes`'
    /// samples (perf annotate, whitted_base `--spp 9 --sampler grid`, 1 thread).
    #[inline]
    fn paths(&self, idx: &[u32], out: &mut [u64; 16]) {
        if self.per_pixel == 1 {
            out[..idx.len().min(16)].fill(self.first_path);
            return;
        }
        let pp = self.per_pixel as u64;
        // (position, position mod per_pixel) of the ray before.
        let mut before: Option<(u64, u64)> = None;
        for (o, &q) in out.iter_mut().zip(idx) {
            let x = self.first_r as u64 + q as u64;
            let r = match before {
                Some((bx, br)) if x >= bx && x - bx < pp => {
                    // br + (x - bx) < 2 pp: one subtraction at most.
                    let r = br + (x - bx);
                    if r >= pp { r - pp } else { r }
                }
                _ => x % pp,
            };
            before = Some((x, r));
            *o = self.first_path + r;
        }
    }
}

impl RayQueue {
    pub fn clear(&mut self) {
        self.rays.clear();
        self.slot.clear();
        self.weight.clear();
        self.throughput.clear();
        self.path.clear();
        self.camera = None;
    }

    /// Camera sample (accumulator slot) of ray `i`.
    #[inline]
    pub fn slot(&self, i: usize) -> u32 {
        match &self.camera {
            Some(c) => {
                debug_assert!(i < self.rays.len());
                c.first_slot + i as u32
            }
            None => self.slot[i],
        }
    }

    /// The slot of ray 0 where the queue is a camera run (ray `i` in slot
    /// `first + i`, weight and throughput one), else `None`.
    #[inline]
    pub fn camera_first_slot(&self) -> Option<u32> {
        self.camera.map(|c| c.first_slot)
    }

    /// Weight of ray `i`: what its radiance is scaled by.
    #[inline]
    pub fn weight(&self, i: usize) -> Vec3 {
        match &self.camera {
            Some(_) => {
                debug_assert!(i < self.rays.len());
                Vec3::ONE
            }
            None => self.weight[i],
        }
    }

    /// Throughput of ray `i` (contribution cutoff).
    #[inline]
    pub fn throughput(&self, i: usize) -> Vec3 {
        match &self.camera {
            Some(_) => {
                debug_assert!(i < self.rays.len());
                Vec3::ONE
            }
            None => self.throughput[i],
        }
    }

    /// Path identity of ray `i`.
    #[inline]
    pub fn path(&self, i: usize) -> u64 {
        match &self.camera {
            Some(c) => {
                debug_assert!(i < self.rays.len());
                c.path(i)
            }
            None => self.path[i],
        }
    }

    /// The values of the rays `idx` (at most 16; lane `i` gets ray `idx[i]`): slot,
    /// weight (as x, y, z lanes) and time, and with `children` also throughput and path,
    /// what [`slot`](RayQueue::slot), [`weight`](RayQueue::weight),
    /// [`throughput`](RayQueue::throughput) and [`path`](RayQueue::path) return ray by
    /// ray. Whether the queue is a camera run is settled once for the group instead of
    /// once per value (a `match` in every accessor call).
    ///
    /// Measured before (perf, whitted_aa3x3 and whitted_blur16, 1 thread): the
    /// accessors called per hit of a shading lane group were 5-6 % of
    /// `shade_group_lanes`' samples.
    pub fn gather(
        &self,
        idx: &[u32],
        slot: &mut [u32; 16],
        weight: &mut [[f32; 16]; 3],
        time: &mut [f32; 16],
        children: Option<(&mut [Vec3; 16], &mut [u64; 16])>,
    ) {
        let idx = &idx[..idx.len().min(16)];
        for (i, &q) in idx.iter().enumerate() {
            time[i] = self.rays[q as usize].time;
        }
        match &self.camera {
            Some(c) => {
                for (i, &q) in idx.iter().enumerate() {
                    debug_assert!((q as usize) < self.rays.len());
                    slot[i] = c.first_slot + q;
                }
                for w in weight.iter_mut() {
                    w[..idx.len()].fill(1.0);
                }
                if let Some((throughput, path)) = children {
                    throughput[..idx.len()].fill(Vec3::ONE);
                    c.paths(idx, path);
                }
            }
            None => {
                let (slots, weights) = (&self.slot[..], &self.weight[..]);
                for (i, &q) in idx.iter().enumerate() {
                    let q = q as usize;
                    slot[i] = slots[q];
                    let w = weights[q];
                    (weight[0][i], weight[1][i], weight[2][i]) = (w.x, w.y, w.z);
                }
                if let Some((throughput, path)) = children {
                    let (throughputs, paths) = (&self.throughput[..], &self.path[..]);
                    for (i, &q) in idx.iter().enumerate() {
                        throughput[i] = throughputs[q as usize];
                        path[i] = paths[q as usize];
                    }
                }
            }
        }
    }

    /// Writes out the per-ray values a camera run implies, so the queue can take rays
    /// of any kind.
    fn materialize(&mut self) {
        let Some(c) = self.camera.take() else {
            return;
        };
        let n = self.rays.len();
        self.slot.extend(c.first_slot..c.first_slot + n as u32);
        self.weight.resize(n, Vec3::ONE);
        self.throughput.resize(n, Vec3::ONE);
        self.path.extend((0..n).map(|i| c.path(i)));
    }

    /// Appends camera rays: consecutive accumulator slots from `first_slot`, weight and
    /// throughput one, and path `first_path + (r + i) mod per_pixel` for ray `i` (`r`
    /// the position of the first ray in its pixel: camera rays are numbered within
    /// their pixel). When the queue is empty the rays are taken whole, without a copy
    /// (`rays` gets the queue's old buffer, emptied); else they are moved over. Only
    /// the rays are stored (see [`RayQueue`]) while the queue's rays continue one
    /// camera run; otherwise every array is written.
    pub fn append_camera(
        &mut self,
        rays: &mut Vec<Ray>,
        first_slot: u32,
        (first_path, r, per_pixel): (u64, usize, usize),
    ) {
        let k = rays.len();
        let run = CameraRun {
            first_slot,
            first_path,
            first_r: (r % per_pixel.max(1)) as u32,
            per_pixel: per_pixel.max(1) as u32,
        };
        if self.rays.is_empty() && self.slot.is_empty() {
            std::mem::swap(&mut self.rays, rays);
            rays.clear();
            self.camera = Some(run);
            return;
        }
        let n0 = self.rays.len();
        if let Some(c) = self.camera {
            // A continuation: the next slots, the next positions in the pixels.
            let continues = c.first_path == first_path
                && c.per_pixel == run.per_pixel
                && c.first_slot as usize + n0 == first_slot as usize
                && (c.first_r as usize + n0) % c.per_pixel as usize == run.first_r as usize;
            if continues {
                self.rays.append(rays);
                return;
            }
            self.materialize();
        }
        self.rays.append(rays);
        let n = self.rays.len();
        self.slot.extend(first_slot..first_slot + k as u32);
        self.weight.resize(n, Vec3::ONE);
        self.throughput.resize(n, Vec3::ONE);
        self.path.extend((0..k).map(|i| run.path(i)));
    }

    /// Appends rays with their values, one extend of each array (the child rays of a
    /// lane group): `rays`, and per ray its slot, weight, throughput and path, in the
    /// same order and number.
    pub fn extend(
        &mut self,
        rays: impl IntoIterator<Item = Ray>,
        slots: impl IntoIterator<Item = u32>,
        weights: impl IntoIterator<Item = Vec3>,
        throughputs: &[Vec3],
        paths: impl IntoIterator<Item = u64>,
    ) {
        self.extend_with(|r| r.extend(rays), slots, weights, throughputs, paths);
    }

    /// [`RayQueue::extend`] with the rays written by `append_rays` onto the queue's ray
    /// array (a store straight from lanes, `ray_store::append_rays`), after a camera
    /// run's values are written out.
    pub fn extend_with(
        &mut self,
        append_rays: impl FnOnce(&mut Vec<Ray>),
        slots: impl IntoIterator<Item = u32>,
        weights: impl IntoIterator<Item = Vec3>,
        throughputs: &[Vec3],
        paths: impl IntoIterator<Item = u64>,
    ) {
        self.materialize();
        append_rays(&mut self.rays);
        self.slot.extend(slots);
        self.weight.extend(weights);
        self.throughput.extend_from_slice(throughputs);
        self.path.extend(paths);
        let n = self.rays.len();
        debug_assert!(
            self.slot.len() == n
                && self.weight.len() == n
                && self.throughput.len() == n
                && self.path.len() == n,
            "RayQueue::extend: one value of each per ray"
        );
    }

    pub fn push(&mut self, ray: Ray, slot: u32, weight: Vec3, throughput: Vec3, path: u64) {
        self.materialize();
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

/// Test helper: every ray's slot, weight, throughput and path, through the accessors.
#[cfg(test)]
impl RayQueue {
    pub(crate) fn per_ray(&self) -> (Vec<u32>, Vec<Vec3>, Vec<Vec3>, Vec<u64>) {
        let n = self.rays.len();
        (
            (0..n).map(|i| self.slot(i)).collect(),
            (0..n).map(|i| self.weight(i)).collect(),
            (0..n).map(|i| self.throughput(i)).collect(),
            (0..n).map(|i| self.path(i)).collect(),
        )
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

    /// Every per-ray value of `q` through the accessors, as bits.
    fn values(q: &RayQueue) -> Vec<(u32, [u32; 3], [u32; 3], u64)> {
        (0..q.rays.len())
            .map(|i| {
                (
                    q.slot(i),
                    q.weight(i).to_array().map(f32::to_bits),
                    q.throughput(i).to_array().map(f32::to_bits),
                    q.path(i),
                )
            })
            .collect()
    }

    /// A camera run (only the rays stored) hands out, through the accessors, what the
    /// rays pushed one by one with their values written out hold: for 1 and 3 rays per
    /// pixel, a run appended in pieces (continuations stay a run), a piece that does
    /// not continue the run and a push after a run (both write the run out first).
    #[test]
    fn camera_runs_hand_out_what_pushed_rays_store() {
        let ray = |i: usize| Ray::new(Vec3::splat(i as f32), Vec3::X);
        for per_pixel in [1usize, 3] {
            let first_path = 40;
            // (first ray of the piece in generation order, rays, first slot)
            let pieces = [(0usize, 5usize, 7u32), (5, 4, 12), (9, 1, 16), (10, 2, 50)];
            let mut run = RayQueue::default();
            let mut pushed = RayQueue::default();
            for (k, &(r, n, first_slot)) in pieces.iter().enumerate() {
                let mut rays: Vec<Ray> = (r..r + n).map(ray).collect();
                run.append_camera(&mut rays, first_slot, (first_path, r, per_pixel));
                assert!(rays.is_empty());
                for i in 0..n {
                    let path = first_path + ((r + i) % per_pixel) as u64;
                    pushed.push(
                        ray(r + i),
                        first_slot + i as u32,
                        Vec3::ONE,
                        Vec3::ONE,
                        path,
                    );
                }
                // The first three pieces continue one run: nothing but rays stored.
                assert_eq!(run.camera.is_some(), k < 3, "piece {k}");
                assert_eq!(run.slot.is_empty(), k < 3, "piece {k}");
                assert_eq!(run.rays, pushed.rays);
                assert_eq!(
                    values(&run),
                    values(&pushed),
                    "per pixel {per_pixel}, piece {k}"
                );
            }
            let mut fresh = RayQueue::default();
            let mut rays: Vec<Ray> = (0..4).map(ray).collect();
            fresh.append_camera(&mut rays, 3, (first_path, 1, per_pixel));
            let mut want = RayQueue::default();
            for i in 0..4 {
                let path = first_path + ((1 + i) % per_pixel) as u64;
                want.push(ray(i), 3 + i as u32, Vec3::ONE, Vec3::ONE, path);
            }
            assert_eq!(values(&fresh), values(&want));
            let extra = (ray(9), 99, Vec3::new(0.5, 0.25, 2.0), Vec3::splat(0.5), 7);
            fresh.push(extra.0, extra.1, extra.2, extra.3, extra.4);
            want.push(extra.0, extra.1, extra.2, extra.3, extra.4);
            assert!(fresh.camera.is_none());
            assert_eq!(values(&fresh), values(&want));
            fresh.clear();
            assert!(fresh.camera.is_none() && values(&fresh).is_empty());
        }
    }

    /// [`RayQueue::gather`] hands out, lane by lane, what the accessors return ray by
    /// ray: for a camera run (1 and 3 rays per pixel) and for a queue with its values
    /// written out, full and partial lane groups of scattered indices, with and without
    /// the children's values; lanes past the group are left as they were.
    #[test]
    fn gather_hands_out_what_the_accessors_return() {
        let ray = |i: usize| {
            let mut r = Ray::new(Vec3::splat(i as f32), Vec3::X);
            r.time = i as f32 * 0.25;
            r
        };
        let mut queues = Vec::new();
        for per_pixel in [1usize, 3] {
            let mut q = RayQueue::default();
            let mut rays: Vec<Ray> = (0..40).map(ray).collect();
            q.append_camera(&mut rays, 11, (500, 2, per_pixel));
            assert!(q.camera.is_some());
            queues.push(q);
        }
        let mut written = RayQueue::default();
        for i in 0..40u32 {
            let w = Vec3::new(i as f32, 0.5 * i as f32, 3.0 - i as f32);
            written.push(ray(i as usize), 90 - i, w, w * 0.25, 7 * i as u64 + 1);
        }
        queues.push(written);
        let groups: [&[u32]; 3] = [
            &[39, 0, 5, 5, 17, 3, 8, 22, 31, 1, 2, 9, 38, 12, 14, 27],
            &[6, 33, 20],
            &[],
        ];
        for (k, q) in queues.iter().enumerate() {
            for idx in groups {
                for children in [false, true] {
                    let mut slot = [u32::MAX; 16];
                    let mut weight = [[-1.0f32; 16]; 3];
                    let mut time = [-1.0f32; 16];
                    let mut throughput = [Vec3::splat(-1.0); 16];
                    let mut path = [u64::MAX; 16];
                    q.gather(
                        idx,
                        &mut slot,
                        &mut weight,
                        &mut time,
                        children.then_some((&mut throughput, &mut path)),
                    );
                    let at = format!("queue {k}, {} lanes, children {children}", idx.len());
                    for (i, &r) in idx.iter().enumerate() {
                        let r = r as usize;
                        assert_eq!(slot[i], q.slot(r), "{at}: lane {i}");
                        let w = Vec3::new(weight[0][i], weight[1][i], weight[2][i]);
                        assert_eq!(w.to_array(), q.weight(r).to_array(), "{at}: lane {i}");
                        assert_eq!(time[i].to_bits(), q.rays[r].time.to_bits(), "{at}");
                        if children {
                            assert_eq!(throughput[i], q.throughput(r), "{at}: lane {i}");
                            assert_eq!(path[i], q.path(r), "{at}: lane {i}");
                        }
                    }
                    for i in idx.len()..16 {
                        assert_eq!(slot[i], u32::MAX, "{at}: lane {i} past the group");
                        assert_eq!(time[i], -1.0, "{at}: lane {i} past the group");
                        assert!(weight.iter().all(|w| w[i] == -1.0), "{at}: lane {i}");
                        assert_eq!(path[i], u64::MAX, "{at}: lane {i} past the group");
                        assert_eq!(throughput[i], Vec3::splat(-1.0), "{at}: lane {i}");
                    }
                    if !children {
                        assert_eq!(path, [u64::MAX; 16], "{at}: no paths asked for");
                    }
                }
            }
        }
    }

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
