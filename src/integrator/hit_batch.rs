//! The hits of a wave as a structure of arrays, grouped by material ([`HitBatch`]):
//! what the shading stage reads, 16 hits to a lane load.
//!
//! A counting sort on the material index (one pass to count, one to place, queue order
//! kept within a material) puts the hits of one material next to each other, so a lane
//! group shares one shading model and its constants (Laine, Karras and Aila, HPG 2013,
//! sort the queue by material for the same reason). Each hit's surface interaction is
//! then written, in that order, component by component: hit point, error bound,
//! geometric and shading normals, shadow-ray base point, the smooth-mesh flag as a lane
//! mask, side, uv and the unit ray direction. Hits on the static triangle mesh (all of
//! a mesh scene's) and on static spheres are reconstructed 16 at a time in lanes
//! ([`crate::simd::surface::triangle_surfaces`], [`crate::simd::surface::sphere_surfaces`],
//! bit for bit the scalar [`SurfaceInteraction::new`]); the others (planes, instances,
//! moving primitives) go through the scalar constructor.
//!
//! Measured (callgrind, bunny 1024x1024, 1 thread, render phase): building one hit by
//! `SurfaceInteraction::new` and pushing its fields cost about 700 instructions per
//! hit (`corners`, `shading_normal`, `vertex_normals` each re-read the triangle).

use super::interaction::SurfaceInteraction;
use super::shadow::material_of;
use crate::accel::{PrimRef, SceneHit};
use crate::geometry::Ray;
use crate::scene::{Scene, TriangleMesh};
use crate::simd::Lanes;
use crate::simd::Packet;
use crate::simd::kernels::RayLanes;
use crate::simd::lanes3::V3;
use crate::simd::ray_gather::{gather_f32x3, gather_rays, gather_u32};
use crate::simd::surface::{
    SphereHits, Surfaces, TriangleHits, sphere_surfaces, triangle_surfaces,
};
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
    fn set(&mut self, i: usize, v: Vec3) {
        (self.x[i], self.y[i], self.z[i]) = (v.x, v.y, v.z);
    }

    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// The 16 lanes starting at hit `i`.
    #[inline(always)]
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
    /// Queue index of each ray that hit nothing, in queue order (the sort's placement
    /// pass puts them after the hits).
    miss: Vec<u32>,
    /// Scratch of the sort: material of each queue entry, count per material.
    material: Vec<u32>,
    count: Vec<u32>,
}

const MASK_SET: f32 = f32::from_bits(u32::MAX);
/// The material entry of a queue ray that hit nothing.
const MISS: u32 = u32::MAX;

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

    /// The queue indices of the rays that missed, in queue order (of the queue the
    /// batch was last built from).
    ///
    /// Before: a scan of the material of every queue entry for the misses, which the
    /// placement pass had already listed (and cut off): its compare and branch held
    /// about a tenth of `shade_queue`'s samples (perf annotate, whitted_blur16, 1
    /// thread, AVX-512).
    pub fn misses(&self) -> impl Iterator<Item = usize> + '_ {
        self.miss.iter().map(|&i| i as usize)
    }

    /// Hits in the batch.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.ray.len()
    }

    /// Rebuilds the batch from the rays of a queue and their hits (misses are left out).
    pub fn build(&mut self, scene: &Scene, rays: &[Ray], hits: &[Option<SceneHit>]) {
        if scene.materials.len() == 1 {
            self.split_one_material(hits);
        } else {
            self.sort(scene, hits);
        }
        self.fill(scene, rays, hits);
    }

    /// The sort of a scene with one material (every mesh scene without an MTL, the
    /// bunny): every hit has material 0 (`SceneBuilder::finish` checks each
    /// primitive's material index), so hits and misses are split in one pass, each in
    /// queue order, which is what [`sort`](HitBatch::sort) gives there.
    ///
    /// Before: the sort's two passes (each hit's material looked up and its run
    /// counted, then placement) over every queue entry, 1,048,576 per bunny frame.
    /// With the misses' loop of `shade_queue` settled per queue, `shade_queue`'s own
    /// samples went 160 -> 115 (perf record -e cpu-clock, 3 x 3 bunny frames
    /// 1024x1024, 1 thread, interleaved, load ~6).
    fn split_one_material(&mut self, hits: &[Option<SceneHit>]) {
        let n = hits.len();
        self.material.resize(n, 0);
        self.ray.resize(n, 0);
        self.miss.resize(n, 0);
        let (mut at_hit, mut at_miss) = (0, 0);
        for (i, (m, hit)) in self.material.iter_mut().zip(hits).enumerate() {
            let missed = hit.is_none();
            *m = if missed { MISS } else { 0 };
            // Both written, one kept (no branch on the hit): `at_hit + at_miss == i`.
            self.ray[at_hit] = i as u32;
            self.miss[at_miss] = i as u32;
            at_hit += !missed as usize;
            at_miss += missed as usize;
        }
        self.ray.truncate(at_hit);
        self.miss.truncate(at_miss);
        self.groups.clear();
        if at_hit > 0 {
            self.groups.push((0, 0..at_hit));
        }
    }

    /// The counting sort of the queue's entries by material (see the module).
    fn sort(&mut self, scene: &Scene, hits: &[Option<SceneHit>]) {
        // Counting sort on the material index: material m in bucket m + 1, the misses
        // in bucket 0 (placed after every hit and cut off; a material index past the
        // scene's is out of bounds, as before).
        let materials = scene.materials.len();
        let bucket = |m: u32| m.wrapping_add(1) as usize;
        self.count.clear();
        self.count.resize(materials + 1, 0);
        // Written by index over a sized array, not pushed (a capacity check per hit was
        // a quarter of `shade_queue`'s own time, whitted_aa3x3).
        self.material.resize(hits.len(), 0);
        // Queue order holds runs of one material (neighbouring pixels see the same
        // surface), so the count of the current run is kept in a register and added
        // to its bucket when the run ends: a count per hit in memory made every hit
        // wait on the store of the one before (the same counter).
        let (mut cur, mut run) = (MISS, 0u32);
        for (m, hit) in self.material.iter_mut().zip(hits) {
            *m = material_at(scene, hit);
            if *m != cur {
                self.count[bucket(cur)] += run;
                (cur, run) = (*m, 0);
            }
            run += 1;
        }
        self.count[bucket(cur)] += run;
        self.groups.clear();
        let mut start = 0;
        for m in 0..materials {
            let n = self.count[m + 1] as usize;
            // Prefix sum: the bucket of material m becomes its first slot.
            self.count[m + 1] = start as u32;
            if n > 0 {
                self.groups.push((m as u32, start..start + n));
            }
            start += n;
        }
        // The misses after every hit.
        let n_hits = start;
        start += self.count[0] as usize;
        self.count[0] = n_hits as u32;
        self.ray.clear();
        self.ray.resize(start, 0);
        // The next slot of the current run in a register, as above.
        let (mut cur, mut at) = (bucket(MISS), self.count[bucket(MISS)]);
        for (i, &m) in self.material.iter().enumerate() {
            let b = bucket(m);
            if b != cur {
                self.count[cur] = at;
                (cur, at) = (b, self.count[b]);
            }
            self.ray[at as usize] = i as u32;
            at += 1;
        }
        self.miss.clear();
        self.miss.extend_from_slice(&self.ray[n_hits..]);
        self.ray.truncate(n_hits);
    }

    /// Writes the surface interaction of every sorted hit into the columns: hits on
    /// the static triangle mesh and on static spheres 16 at a time in lanes
    /// ([`triangle_surfaces`], [`sphere_surfaces`]; a lane group holding both computes
    /// both and selects), the others (planes, instances, moving primitives) one by one through
    /// [`SurfaceInteraction::new`], the oracle of the lanes. Then zeroes the padding.
    ///
    /// The lanes' rays are loaded transposed ([`gather_rays`]), and a lane group whose
    /// triangle (or sphere) lanes all hit one primitive takes its corners (centre and
    /// radius) as one splat instead of lane by lane: the gathers were about half
    /// of this function's samples (perf annotate, whitted_base aa3x3, 1 thread),
    /// and most lane groups of a scene of large primitives hit one. `fill` went from
    /// 140.7 M to 99.0 M instructions (callgrind, whitted_base, 1 thread), the sort
    /// before it from 42.8 M to 29.8 M.
    ///
    /// Tried and not kept: lane groups starting at each material group's first hit (so
    /// that a lane group holds both kinds only where one material covers triangles and
    /// spheres): `fill` went from 140.7 M to 146.6 M instructions (callgrind,
    /// whitted_base, 1 thread): the partial groups it adds cost more than the merged
    /// groups it saves.
    fn fill(&mut self, scene: &Scene, rays: &[Ray], hits: &[Option<SceneHit>]) {
        let n = self.ray.len();
        // Every entry below `n` is written below, and the padding `n..n + LANES` is
        // zeroed at the end: the columns only grow (to the largest wave seen), never
        // cut, so a wave smaller than the last one writes no zeros past its padding
        // (cut and grown again, the growth was zero-filled anew at every larger wave:
        // `Vec::extend_with`, 2.6 % of the whitted_base process). Entries past
        // `n + LANES` are stale and never read.
        let len = n + LANES;
        for a in self.vec3_columns() {
            for c in [&mut a.x, &mut a.y, &mut a.z] {
                if c.len() < len {
                    c.resize(len, 0.0);
                }
            }
        }
        for c in [&mut self.smooth, &mut self.front] {
            if c.len() < len {
                c.resize(len, 0.0);
            }
        }
        self.uv.resize(n, Vec2::ZERO);
        let mesh = &scene.mesh;
        let with_normals = mesh.has_normals();
        let textured = |m: u32| !scene.materials[m as usize].textures.is_empty();
        // No image texture in the scene: the uv of a lane hit is zero, written a
        // whole lane group at a time below rather than looked up hit by hit.
        let any_textured = scene.materials.iter().any(|m| !m.textures.is_empty());
        let g = Gather;
        let mut sg = SphereGather::default();
        // Lanes of another kind, or past the last hit, keep stale values: lanes never
        // mix. Two buffers: each lane group's hit data is stored one lane group ahead
        // (before the lane group before it is computed) and read as lanes a lane group
        // later, by when the scalar stores have left the store buffer.
        //
        // Before: stored lane by lane right before its 64-byte loads, which then
        // waited for the sixteen stores (a load spanning several in-flight stores is
        // not forwarded): the instruction after the first such load held 9 % of this
        // function's samples (perf annotate, whitted_blur16, 1 thread, AVX-512).
        // After (perf record -e cpu-clock, 1 thread, host load ~5, `fill`'s samples
        // over `TinyGroup::closest`'s, which this does not touch): aa3x3 1.72/1.76/1.81
        // -> 1.45/1.71/1.71 (3 runs each); whitted_base at 1 spp 1.67/1.68/1.73 ->
        // 1.57/1.88/2.03: no gain there that the noise does not cover.
        let mut buffers = [HitLanes::default(), HitLanes::default()];
        let mut kinds = (0, 0);
        if n > 0 {
            kinds = hit_lanes(&self.ray[..n.min(LANES)], hits, &mut buffers[0]);
        }
        for k0 in (0..n).step_by(LANES) {
            let m = (n - k0).min(LANES);
            let [even, odd] = &mut buffers;
            let (cur, ahead) = if (k0 / LANES).is_multiple_of(2) {
                (&*even, odd)
            } else {
                (&*odd, even)
            };
            // Lanes on the static mesh and on static spheres; the rest through the
            // scalar path.
            let (triangles, spheres) = kinds;
            if k0 + LANES < n {
                let next = &self.ray[k0 + LANES..(k0 + 2 * LANES).min(n)];
                kinds = hit_lanes(next, hits, ahead);
            }
            // The lanes past the last hit repeat the first hit's ray (any ray will do:
            // lanes never mix, and the padding is zeroed at the end); a full lane
            // group reads its indices where the sort wrote them.
            //
            // Before: every lane group copied its indices into a padded array first
            // (a call to `memmove` for a run-time length) and read them back from it
            // one by one: the instruction after that read held a fifth of this
            // function's samples (perf annotate, whitted_base aa3x3, 1 thread,
            // AVX-512). Without the copy, whitted aa3x3 CPU time 801 -> 786 ms (medians
            // of 5 interleaved runs, `perf stat -e task-clock`, host load ~13 on 2
            // cores: within the noise of one run, but 4 of 5 runs faster).
            let mut pad = [self.ray[k0]; LANES];
            if m < LANES {
                pad[..m].copy_from_slice(&self.ray[k0..k0 + m]);
            }
            let lanes = triangles | spheres;
            // One lane form where the group holds one kind (each call inlined, writing
            // straight into the columns), both merged by a select where it holds both.
            if lanes != 0 {
                let idx: &[u32; LANES] = match self.ray[k0..].first_chunk() {
                    Some(full) if m == LANES => full,
                    _ => &pad,
                };
                let (r, _) = gather_rays(rays, idx);
                if spheres == 0 {
                    let h = g.hits(mesh, with_normals, triangles, cur, &r);
                    self.put(k0, &triangle_surfaces(&h));
                } else if triangles == 0 {
                    let h = sg.hits(scene, spheres, cur, &r);
                    self.put(k0, &sphere_surfaces(&h));
                } else {
                    let (t, s) = (
                        triangle_surfaces(&g.hits(mesh, with_normals, triangles, cur, &r)),
                        sphere_surfaces(&sg.hits(scene, spheres, cur, &r)),
                    );
                    self.put(
                        k0,
                        &Surfaces::select(Packet::mask_from_bits(spheres), &s, &t),
                    );
                }
            }
            let all = if m == LANES { 0xffff } else { (1u32 << m) - 1 };
            if !any_textured && lanes == all {
                self.uv[k0..k0 + m].fill(Vec2::ZERO);
                continue;
            }
            for l in 0..m {
                let k = k0 + l;
                let i = self.ray[k] as usize;
                let (ray, hit) = (&rays[i], hits[i].as_ref().expect("a hit"));
                let material = self.material[i];
                if lanes >> l & 1 == 1 {
                    self.uv[k] = if textured(material) {
                        super::texturing::hit_uv(scene, ray, hit)
                    } else {
                        Vec2::ZERO
                    };
                    continue;
                }
                let si = SurfaceInteraction::new(scene, ray, hit);
                debug_assert_eq!(si.material, material);
                self.set(k, &si, ray.dir.normalize());
            }
        }
        // Padding for the last lane load: zero, whatever the last lanes computed.
        for a in self.vec3_columns() {
            for c in [&mut a.x, &mut a.y, &mut a.z] {
                c[n..len].fill(0.0);
            }
        }
        self.smooth[n..len].fill(0.0);
        self.front[n..len].fill(0.0);
    }

    /// Hits `k0..k0 + LANES` from their lane interactions.
    #[inline(always)]
    fn put(&mut self, k0: usize, s: &Surfaces) {
        let put = |a: &mut Soa3, v: &V3| {
            a.x[k0..k0 + LANES].copy_from_slice(&v.x.to_array());
            a.y[k0..k0 + LANES].copy_from_slice(&v.y.to_array());
            a.z[k0..k0 + LANES].copy_from_slice(&v.z.to_array());
        };
        put(&mut self.p, &s.p);
        put(&mut self.p_error, &s.p_error);
        put(&mut self.ng, &s.ng);
        put(&mut self.ns, &s.ns);
        put(&mut self.base, &s.base);
        put(&mut self.dir, &s.dir);
        self.smooth[k0..k0 + LANES].copy_from_slice(&s.smooth.to_array());
        self.front[k0..k0 + LANES].copy_from_slice(&s.front.to_array());
    }

    /// Hit `k` from its scalar interaction and unit ray direction.
    fn set(&mut self, k: usize, si: &SurfaceInteraction, dir: Vec3) {
        self.p.set(k, si.p);
        self.p_error.set(k, si.p_error);
        self.ng.set(k, si.n_geometric);
        self.ns.set(k, si.n_shading);
        self.base.set(k, si.p_shadow.unwrap_or(si.p));
        self.smooth[k] = if si.p_shadow.is_some() { MASK_SET } else { 0.0 };
        self.front[k] = if si.front_face { MASK_SET } else { 0.0 };
        self.uv[k] = si.uv;
        self.dir.set(k, dir);
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

/// Per lane of one lane group: the primitive index (of the kind the lane's bit says)
/// and the hit's distance and barycentrics.
#[derive(Default)]
struct HitLanes {
    prim: [u32; LANES],
    t: [f32; LANES],
    u: [f32; LANES],
    v: [f32; LANES],
}

/// The hit data of one lane group's hits (queue indices `ray`, at most [`LANES`]) into
/// `out`, lane by lane: `(triangles, spheres)`, the lanes on the static mesh and on
/// static spheres (their primitive in `out.prim`; other lanes keep stale values).
#[inline(always)]
fn hit_lanes(ray: &[u32], hits: &[Option<SceneHit>], out: &mut HitLanes) -> (u32, u32) {
    let (mut triangles, mut spheres) = (0u32, 0u32);
    for (l, &i) in ray.iter().enumerate().take(LANES) {
        let hit = hits[i as usize].as_ref().expect("sorted entries are hits");
        match hit.prim {
            PrimRef::Triangle(t) => {
                triangles |= 1 << l;
                out.prim[l] = t;
            }
            PrimRef::Sphere(s) => {
                spheres |= 1 << l;
                out.prim[l] = s;
            }
            _ => {}
        }
        (out.t[l], out.u[l], out.v[l]) = (hit.t, hit.u, hit.v);
    }
    (triangles, spheres)
}

/// The primitive shared by the lanes of `mask` (non-zero), if they all hit one.
#[inline(always)]
fn shared_prim(mask: u32, prim: &[u32; LANES]) -> Option<usize> {
    let first = prim[mask.trailing_zeros() as usize];
    let same = (0..LANES).all(|l| mask >> l & 1 == 0 || prim[l] == first);
    same.then_some(first as usize)
}

/// The lanes of `mask`, bit by bit.
#[inline(always)]
fn for_each_lane(mut mask: u32, mut f: impl FnMut(usize)) {
    while mask != 0 {
        f(mask.trailing_zeros() as usize);
        mask &= mask - 1;
    }
}

/// The material of a queue entry's hit, [`MISS`] where it hit nothing.
#[inline(always)]
fn material_at(scene: &Scene, hit: &Option<SceneHit>) -> u32 {
    match hit {
        None => MISS,
        // The static mesh and spheres inline (a call per hit otherwise).
        Some(SceneHit {
            prim: PrimRef::Triangle(t),
            ..
        }) => scene.mesh.material[*t as usize],
        Some(SceneHit {
            prim: PrimRef::Sphere(s),
            ..
        }) => scene.spheres.material[*s as usize],
        Some(h) => material_of(scene, h.prim),
    }
}

/// The triangle lanes' corner positions and raw vertex normals from the mesh for
/// [`triangle_surfaces`] (lanes of other kinds hold zeros or stale values: lanes never
/// mix). No scratch since the lanes are hardware gathers.
struct Gather;

impl Gather {
    /// The triangle hits of the lanes `mask` of `h` (rays `r`) on `mesh`.
    #[inline(always)]
    fn hits(
        &self,
        mesh: &TriangleMesh,
        with_normals: bool,
        mask: u32,
        h: &HitLanes,
        r: &RayLanes<Packet>,
    ) -> TriangleHits {
        let raw_normal = |vi: u32| {
            let vi = vi as usize;
            Vec3::new(mesh.nxs[vi], mesh.nys[vi], mesh.nzs[vi])
        };
        let corner_ids = |t: usize| [mesh.i0[t], mesh.i1[t], mesh.i2[t]];
        let (corners, normals) = if let Some(t) = shared_prim(mask, &h.prim) {
            // Written out, not by `array::map`: that stayed an out-of-line
            // `core::array::try_map` call (see `PacketBounds::triangle_candidates`).
            let [c0, c1, c2] = mesh.corners(t);
            let [i0, i1, i2] = corner_ids(t);
            let normal = |vi: u32| V3::splat(raw_normal(vi));
            (
                [V3::splat(c0), V3::splat(c1), V3::splat(c2)],
                // An `if`, not `bool::then`: its closure stayed out of line.
                if with_normals {
                    Some([normal(i0), normal(i1), normal(i2)])
                } else {
                    None
                },
            )
        } else {
            // Hardware gathers (`gather_u32`, `gather_f32`): each lane group's sixteen
            // corner indices, then each coordinate of the sixteen corners, loaded at
            // once, where the lane loop before had a few lanes' loads in flight, each
            // read waiting on a cache miss (the instruction after the index load held
            // 11 % of `fill`'s samples, perf annotate, bunny 1024x1024, 1 thread,
            // AVX-512).
            //
            // The lane loop (before): the arrays' pointers and lengths in locals, and
            // the lanes walked in a plain loop. Before that: a closure per lane that the compiler kept out of line,
            // reloading each array from the mesh per read. Measured with the one-pass
            // split below (perf record -e cpu-clock, 3 x 3 bunny frames 1024x1024, 1
            // thread, interleaved, load ~6): `fill` with its gathers 286 -> 260
            // samples. Tried: a pass per array (the corners' indices, then positions,
            // then normals): 426 -> 516 samples (ten walks of the lane mask instead of
            // one, each read still waiting on a cache miss). Tried: prefetching the
            // next lane group's corner indices (`prefetch` of `i0`, `i1`, `i2` at each
            // of its triangles, where most of the samples wait): `fill` 308 -> 254 and
            // 222 -> 252 samples in two interleaved rounds, `packet_closest` moving
            // -10 % and +10 % with the host (3 x 3 bunny frames each, load ~6): no
            // gain that the noise does not cover.
            let m = mask & 0xffff;
            let vi = [
                gather_u32(&mesh.i0, &h.prim, m),
                gather_u32(&mesh.i1, &h.prim, m),
                gather_u32(&mesh.i2, &h.prim, m),
            ];
            // Not a closure: that stayed out of line, six calls per lane group
            // (`gather_f32x3`).
            #[inline(always)]
            fn at(xyz: [&[f32]; 3], v: &[u32; LANES], m: u32) -> V3 {
                let [x, y, z] = gather_f32x3(xyz, v, m);
                V3 { x, y, z }
            }
            let xyz = [&mesh.xs[..], &mesh.ys[..], &mesh.zs[..]];
            let nxyz = [&mesh.nxs[..], &mesh.nys[..], &mesh.nzs[..]];
            (
                [at(xyz, &vi[0], m), at(xyz, &vi[1], m), at(xyz, &vi[2], m)],
                if with_normals {
                    Some([
                        at(nxyz, &vi[0], m),
                        at(nxyz, &vi[1], m),
                        at(nxyz, &vi[2], m),
                    ])
                } else {
                    None
                },
            )
        };
        TriangleHits {
            corners,
            normals,
            u: Packet::new(h.u),
            v: Packet::new(h.v),
            dir: V3 {
                x: r.d[0],
                y: r.d[1],
                z: r.d[2],
            },
        }
    }
}

/// Scratch of the sphere lanes where a lane group's sphere lanes hit several static
/// spheres: centre and radius (other lanes stale, as in [`Gather`]).
#[derive(Default)]
struct SphereGather {
    center: [[f32; LANES]; 3],
    radius: [f32; LANES],
}

impl SphereGather {
    /// The static sphere hits of the lanes `mask` of `h` (rays `r`) in `scene`.
    #[inline(always)]
    fn hits(&mut self, scene: &Scene, mask: u32, h: &HitLanes, r: &RayLanes<Packet>) -> SphereHits {
        let spheres = &scene.spheres;
        let (center, radius) = if let Some(s) = shared_prim(mask, &h.prim) {
            (
                V3::splat(spheres.center(s)),
                Packet::splat(spheres.radius[s]),
            )
        } else {
            for_each_lane(mask, |l| {
                let s = h.prim[l] as usize;
                let c = spheres.center(s);
                for a in 0..3 {
                    self.center[a][l] = c[a];
                }
                self.radius[l] = spheres.radius[s];
            });
            (
                V3::load(&self.center[0], &self.center[1], &self.center[2]),
                Packet::new(self.radius),
            )
        };
        let v3 = |a: &[Packet; 3]| V3 {
            x: a[0],
            y: a[1],
            z: a[2],
        };
        SphereHits {
            center,
            radius,
            origin: v3(&r.o),
            dir: v3(&r.d),
            t: Packet::new(h.t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{AccelKind, SceneAccel};
    use crate::scene::load::load_scene;
    use crate::test_rng::xorshift64;

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// The camera rays through the pixel centres of a 64x48 image of `scene`, row
    /// by row.
    fn pixel_rays(scene: &Scene) -> Vec<Ray> {
        let (w, h) = (64, 48);
        let frame = scene.camera.frame(w, h);
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| frame.ray(x as f32 + 0.5, y as f32 + 0.5))
            .collect()
    }

    /// `rays` in a random order drawn from `next` (Fisher-Yates).
    fn shuffle(rays: &mut [Ray], next: &mut impl FnMut() -> u64) {
        for i in (1..rays.len()).rev() {
            rays.swap(i, (next() % (i as u64 + 1)) as usize);
        }
    }

    /// In a scene of one material, `build`'s one-pass split gives the batch the
    /// counting sort gives (the same hits in the same order, the same misses and
    /// group, every column bit for bit), on a mesh's camera rays in pixel order and
    /// shuffled (a hit and a miss alternating), with and without misses at the ends.
    #[test]
    fn one_material_split_is_the_sort() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/gem.obj");
        let mut scene = load_scene(&path).expect("gem.obj");
        // The gem's two materials made one (as a mesh without an MTL has).
        scene.materials.truncate(1);
        scene.mesh.material.fill(0);
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let mut rays = pixel_rays(&scene);
        let mut next = xorshift64(0x5eed_0e0e_0001);
        let (mut split, mut sorted) = (HitBatch::default(), HitBatch::default());
        let (mut hits_seen, mut misses_seen) = (0, 0);
        for round in 0..3 {
            if round > 0 {
                shuffle(&mut rays, &mut next);
            }
            // Round 2: only the middle of the queue (fewer rays than the last round:
            // stale entries of a longer batch must not show).
            let rays = if round == 2 {
                &rays[100..2000]
            } else {
                &rays[..]
            };
            let hits: Vec<_> = rays.iter().map(|r| accel.closest_hit(r)).collect();
            split.build(&scene, rays, &hits);
            sorted.sort(&scene, &hits);
            sorted.fill(&scene, rays, &hits);
            let name = format!("round {round}");
            assert_eq!(split.ray, sorted.ray, "{name}: hits");
            assert_eq!(split.groups, sorted.groups, "{name}: groups");
            assert_eq!(split.miss, sorted.miss, "{name}: misses");
            let n = split.ray.len();
            assert_eq!(split.material[..hits.len()], sorted.material[..hits.len()]);
            let col = |b: &HitBatch| -> Vec<Vec<u32>> {
                let mut v: Vec<Vec<u32>> = [&b.p, &b.p_error, &b.ng, &b.ns, &b.base, &b.dir]
                    .iter()
                    .flat_map(|a| [&a.x, &a.y, &a.z])
                    .chain([&b.smooth, &b.front])
                    .map(|c| c[..n + LANES].iter().map(|f| f.to_bits()).collect())
                    .collect();
                v.push(
                    b.uv[..n]
                        .iter()
                        .flat_map(|u| u.to_array())
                        .map(f32::to_bits)
                        .collect(),
                );
                v
            };
            assert_eq!(col(&split), col(&sorted), "{name}: columns");
            hits_seen += n;
            misses_seen += split.miss.len();
        }
        assert!(
            hits_seen > 500 && misses_seen > 500,
            "{hits_seen} {misses_seen}"
        );
    }

    /// On the camera rays of every shipped scene, the batch holds every hit once,
    /// grouped by material in queue order within a group, and gives back exactly
    /// (bit for bit, every field) the interaction `SurfaceInteraction::new` builds and
    /// the unit ray direction, whether the hit went through the lanes (static
    /// triangles) or the scalar path; the padding past the last hit is zero.
    #[test]
    fn batch_is_a_material_sorted_copy_of_the_interactions() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .expect("scenes/")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        paths.sort();
        let (mut triangle, mut sphere, mut smooth, mut other, mut grouped) = (0, 0, 0, 0, 0);
        // One batch for every scene, as a worker reuses it from wave to wave: nothing of
        // an earlier, larger batch may show through.
        let mut batch = HitBatch::default();
        let (mut mixed, mut misses) = (0, 0);
        // Lane groups whose triangle (sphere) lanes hit one primitive (its data
        // splat) and several (gathered lane by lane).
        let (mut one_triangle, mut several_triangles) = (0, 0);
        let (mut one_sphere, mut several_spheres) = (0, 0);
        let mut next = xorshift64(0x5eed_1234_abcd_0001);
        // Every scene in pixel order (runs of one material, as a queue holds them) and
        // shuffled (a material change at almost every hit: the counting sort's runs
        // at their shortest).
        for (path, shuffled) in paths.iter().flat_map(|p| [(p, false), (p, true)]) {
            let name = format!("{} (shuffled {shuffled})", path.display());
            let scene = load_scene(path).unwrap_or_else(|e| panic!("{name}: {e}"));
            let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
            let mut rays = pixel_rays(&scene);
            if shuffled {
                shuffle(&mut rays, &mut next);
            }
            let hits: Vec<_> = rays.iter().map(|r| accel.closest_hit(r)).collect();
            batch.build(&scene, &rays, &hits);
            let n_hits = hits.iter().filter(|h| h.is_some()).count();
            assert_eq!(batch.len(), n_hits, "{name}");
            let missed: Vec<usize> = (0..hits.len()).filter(|&i| hits[i].is_none()).collect();
            assert_eq!(batch.misses().collect::<Vec<_>>(), missed, "{name}: misses");
            misses += missed.len();
            grouped += (batch.groups.len() >= 2) as usize;
            let mut seen = vec![false; rays.len()];
            let mut covered = 0;
            let mut last_material = None;
            for (m, range) in &batch.groups {
                assert!(last_material < Some(*m), "{name}: groups in material order");
                last_material = Some(*m);
                assert_eq!(range.start, covered, "{name}");
                covered = range.end;
                let idx = &batch.ray[range.clone()];
                assert!(idx.windows(2).all(|w| w[0] < w[1]), "{name}: queue order");
                for (k, &i) in range.clone().zip(idx) {
                    let i = i as usize;
                    assert!(!seen[i], "{name}: ray {i} twice");
                    seen[i] = true;
                    let hit = hits[i].as_ref().expect("a hit");
                    let want = SurfaceInteraction::new(&scene, &rays[i], hit);
                    let got = batch.interaction(k, *m);
                    let at = format!("{name}: ray {i} ({:?})", hit.prim);
                    assert_eq!(bits(got.p), bits(want.p), "{at}: p");
                    assert_eq!(bits(got.p_error), bits(want.p_error), "{at}: p_error");
                    assert_eq!(bits(got.n_geometric), bits(want.n_geometric), "{at}");
                    assert_eq!(bits(got.n_shading), bits(want.n_shading), "{at}");
                    assert_eq!(got.p_shadow.map(bits), want.p_shadow.map(bits), "{at}");
                    assert_eq!(got.front_face, want.front_face, "{at}: side");
                    assert_eq!(got.material, want.material, "{at}: material");
                    assert_eq!(got.uv.to_array(), want.uv.to_array(), "{at}: uv");
                    assert_eq!(bits(batch.dir.get(k)), bits(rays[i].dir.normalize()));
                    match hit.prim {
                        PrimRef::Triangle(_) => triangle += 1,
                        PrimRef::Sphere(_) => sphere += 1,
                        _ => other += 1,
                    }
                    smooth += want.p_shadow.is_some() as usize;
                }
            }
            assert_eq!(covered, n_hits, "{name}");
            // Lane groups holding both triangle and sphere hits (both lane forms, merged).
            for group in batch.ray.chunks(LANES) {
                let kind = |i: &u32| hits[*i as usize].map(|h| h.prim);
                let tri = group
                    .iter()
                    .any(|i| matches!(kind(i), Some(PrimRef::Triangle(_))));
                let sph = group
                    .iter()
                    .any(|i| matches!(kind(i), Some(PrimRef::Sphere(_))));
                mixed += (tri && sph) as usize;
                let prims = |want: fn(PrimRef) -> Option<u32>| {
                    let mut p: Vec<u32> = group
                        .iter()
                        .filter_map(|i| kind(i).and_then(want))
                        .collect();
                    p.sort_unstable();
                    p.dedup();
                    p.len()
                };
                match prims(|p| match p {
                    PrimRef::Triangle(t) => Some(t),
                    _ => None,
                }) {
                    0 => {}
                    1 => one_triangle += 1,
                    _ => several_triangles += 1,
                }
                match prims(|p| match p {
                    PrimRef::Sphere(s) => Some(s),
                    _ => None,
                }) {
                    0 => {}
                    1 => one_sphere += 1,
                    _ => several_spheres += 1,
                }
            }
            // The padding of the last lane load is zero (the columns may be longer:
            // they keep the length of the largest batch built).
            let pad = n_hits..n_hits + LANES;
            for a in [&batch.p, &batch.p_error, &batch.ng, &batch.ns, &batch.base] {
                for c in [&a.x, &a.y, &a.z] {
                    assert!(c.len() >= n_hits + LANES, "{name}");
                    assert!(c[pad.clone()].iter().all(|&x| x.to_bits() == 0), "{name}");
                }
            }
            assert!(batch.smooth[pad.clone()].iter().all(|&x| x.to_bits() == 0));
            assert!(batch.front[pad].iter().all(|&x| x.to_bits() == 0));
        }
        eprintln!(
            "{} scenes: {triangle} triangle hits in lanes ({smooth} smooth), {sphere} sphere \
             hits in lanes, {other} others; {mixed} lane groups of both; lane groups of \
             one triangle {one_triangle}, of several {several_triangles}, of one sphere \
             {one_sphere}, of several {several_spheres}",
            paths.len()
        );
        assert!(
            one_triangle > 100 && several_triangles > 100,
            "triangle lane groups"
        );
        assert!(
            one_sphere > 100 && several_spheres > 100,
            "sphere lane groups"
        );
        assert!(misses > 1_000, "{misses} misses compared");
        assert!(
            mixed > 0,
            "no lane group held both a triangle and a sphere hit"
        );
        assert!(paths.len() >= 10, "{} shipped scenes", paths.len());
        assert!(
            grouped >= 3,
            "scenes with several materials in view: {grouped}"
        );
        assert!(triangle > 5_000 && smooth > 200 && sphere > 2_000 && other > 1_000);
    }
}
