//! Uniform grid with 3D-DDA traversal (Amanatides & Woo, "A Fast Voxel Traversal
//! Algorithm for Ray Tracing", Eurographics 1987) and per-ray mailboxing.

use super::spatial::{
    CountedTraversal, LeafSink, Mailbox, TraversalCounts, clip, conservative_pad, grown,
    moves_along,
};
use super::{AccelInfo, Primitives};
use crate::geometry::{Aabb, RayQuery};
use glam::Vec3;
use std::time::Instant;

/// Build and traversal parameters of a [`Grid`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridOptions {
    /// Cells per axis; `None` chooses
    /// `res_a = clamp(round(3 * cbrt(n) * e_a / e_max), 1, 1024)` for a scene box of
    /// extents `e` (about `3 cbrt(n)` cells along the longest axis, proportionally fewer
    /// along the others), halved on every axis while the cell references would exceed
    /// `max(32 n, 2^20)`, which bounds memory for degenerate inputs.
    pub resolution: Option<[u32; 3]>,
    /// Skip primitives this ray already tested in an earlier cell.
    pub mailbox: bool,
    /// Assign primitives to the cells they overlap (separating-axis triangle/box test,
    /// Arvo's sphere/box test) instead of every cell their bounds overlap.
    pub exact_overlap: bool,
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            resolution: None,
            mailbox: true,
            exact_overlap: true,
        }
    }
}

/// Largest automatic resolution per axis.
const MAX_RES: u32 = 1024;

/// A uniform grid over one primitive set, stored CSR-style: the primitive ids of cell
/// `c` are `refs[offsets[c]..offsets[c + 1]]`, cells in x-fastest order.
pub struct Grid<P: Primitives> {
    prims: P,
    /// Scene bounds grown by the assignment margin (empty for no primitives).
    bounds: Aabb,
    res: [i32; 3],
    cell_size: Vec3,
    inv_cell_size: Vec3,
    offsets: Vec<u32>,
    refs: Vec<u32>,
    opts: GridOptions,
    info: AccelInfo,
}

/// The automatic resolution of the issue: `3 cbrt(n)` along the longest axis.
fn auto_resolution(n: usize, extent: Vec3) -> [u32; 3] {
    let e_max = extent.max_element();
    let k = 3.0 * (n as f32).cbrt();
    let mut res = [1u32; 3];
    for (a, r) in res.iter_mut().enumerate() {
        if e_max > 0.0 {
            *r = ((k * extent[a] / e_max).round() as u32).clamp(1, MAX_RES);
        }
    }
    res
}

impl<P: Primitives> Grid<P> {
    pub fn build(prims: P) -> Self {
        Self::build_with(prims, GridOptions::default())
    }

    pub fn build_with(prims: P, opts: GridOptions) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let scene = (0..n).fold(Aabb::EMPTY, |b, i| b.union(&prims.bounds(i)));
        let pad = conservative_pad(&scene);
        let bounds = if n == 0 {
            Aabb::EMPTY
        } else {
            grown(&scene, pad)
        };
        let extent = bounds.extent();
        let mut res = opts
            .resolution
            .map(|r| r.map(|x| x.max(1)))
            .unwrap_or_else(|| auto_resolution(n, extent));

        // Per-primitive cell ranges of the grown bounds; coarsen while too many refs.
        let budget = (32 * n as u64).max(1 << 20);
        let mut ranges: Vec<([i32; 3], [i32; 3])> = Vec::with_capacity(n);
        let (cell_size, inv_cell_size) = loop {
            let cell_size = extent / Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32);
            let inv = Vec3::select(
                cell_size.cmpgt(Vec3::ZERO),
                Vec3::ONE / cell_size,
                Vec3::ZERO,
            );
            ranges.clear();
            let mut total = 0u64;
            for i in 0..n {
                let b = grown(&prims.bounds(i), pad);
                let lo = cell_of(b.min, bounds.min, inv, res);
                let hi = cell_of(b.max, bounds.min, inv, res);
                total += (0..3).map(|a| (hi[a] - lo[a] + 1) as u64).product::<u64>();
                ranges.push((lo, hi));
            }
            if total <= budget || opts.resolution.is_some() || res == [1, 1, 1] {
                break (cell_size, inv);
            }
            res = res.map(|r| r.div_ceil(2));
        };
        let res_i = res.map(|r| r as i32);
        let cells = res.iter().map(|&r| r as usize).product::<usize>();

        // Two passes: count, prefix sum, fill (the overlap test runs in both).
        let cell_box = |c: [i32; 3]| {
            let lo = bounds.min + Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * cell_size;
            grown(&Aabb::new(lo, lo + cell_size), pad)
        };
        let for_each_cell = |i: usize, f: &mut dyn FnMut(usize)| {
            let (lo, hi) = ranges[i];
            let single = lo == hi;
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        if single
                            || !opts.exact_overlap
                            || prims.overlaps_box(i, &cell_box([x, y, z]))
                        {
                            f(((z * res_i[1] + y) * res_i[0] + x) as usize);
                        }
                    }
                }
            }
        };
        let mut offsets = vec![0u32; cells + 1];
        for i in 0..n {
            for_each_cell(i, &mut |c| offsets[c + 1] += 1);
        }
        for c in 0..cells {
            offsets[c + 1] += offsets[c];
        }
        let mut fill = offsets.clone();
        let mut refs = vec![0u32; offsets[cells] as usize];
        for i in 0..n {
            for_each_cell(i, &mut |c| {
                refs[fill[c] as usize] = i as u32;
                fill[c] += 1;
            });
        }

        let nonempty = offsets.windows(2).filter(|w| w[1] > w[0]).count();
        let info = AccelInfo {
            name: "grid",
            primitives: n,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            nodes: cells,
            leaves: nonempty,
            max_depth: 1,
            memory_bytes: offsets.len() * 4 + refs.len() * 4 + prims.memory_bytes(),
            sah_cost: 0.0,
        };
        Grid {
            prims,
            bounds,
            res: res_i,
            cell_size,
            inv_cell_size,
            offsets,
            refs,
            opts,
            info,
        }
    }

    /// Cells per axis.
    pub fn resolution(&self) -> [u32; 3] {
        self.res.map(|r| r as u32)
    }

    /// Total primitive references (a primitive counts once per cell it is in).
    pub fn references(&self) -> usize {
        self.refs.len()
    }

    /// The DDA walk shared by closest hit, any hit and filtered queries (`sink`).
    #[inline(always)]
    fn traverse<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        counts: &mut TraversalCounts,
        sink: &mut S,
    ) {
        let Some((t0, _t1)) = clip(&self.bounds, q) else {
            return;
        };
        let entry = q.origin + q.dir * t0;
        let mut cell = cell_of(entry, self.bounds.min, self.inv_cell_size, self.res);
        let mut step = [0i32; 3];
        let mut next_t = [f32::INFINITY; 3];
        for a in 0..3 {
            if moves_along(q, a) {
                step[a] = if q.dir[a] > 0.0 { 1 } else { -1 };
                next_t[a] = self.boundary_t(q, a, cell[a], step[a]);
            }
        }
        let mut mailbox = Mailbox::new();
        loop {
            counts.node::<COUNT>();
            let c = ((cell[2] * self.res[1] + cell[1]) * self.res[0] + cell[0]) as usize;
            let range = self.offsets[c] as usize..self.offsets[c + 1] as usize;
            for &id in &self.refs[range] {
                if self.opts.mailbox && mailbox.seen(id) {
                    continue;
                }
                counts.prim::<COUNT>();
                if sink.test(&self.prims, id, q) {
                    return;
                }
            }
            // Next cell across the nearest boundary. Stop when the closest hit so far (or
            // the ray's own tmax) lies inside this cell: every primitive of a later cell is
            // hit beyond this cell's exit (up to rounding, which the assignment margin
            // covers by putting such primitives in this cell too).
            let axis = if next_t[0] <= next_t[1] && next_t[0] <= next_t[2] {
                0
            } else if next_t[1] <= next_t[2] {
                1
            } else {
                2
            };
            let exit = next_t[axis];
            if sink.tmax() <= exit || step[axis] == 0 {
                return;
            }
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= self.res[axis] {
                return;
            }
            next_t[axis] = self.boundary_t(q, axis, cell[axis], step[axis]);
        }
    }

    /// Distance to the boundary of `cell` the ray leaves through along `a`, computed from
    /// the origin each time (no accumulated increments, so no drift over long walks).
    #[inline(always)]
    fn boundary_t(&self, q: &RayQuery, a: usize, cell: i32, step: i32) -> f32 {
        let plane = if step > 0 { cell + 1 } else { cell };
        let x = self.bounds.min[a] + plane as f32 * self.cell_size[a];
        (x - q.origin[a]) * q.inv_dir[a]
    }
}

/// Cell containing `p`, clamped to the grid (NaN casts to 0, also clamped).
#[inline(always)]
fn cell_of<R: Copy + Into<i64>>(p: Vec3, min: Vec3, inv: Vec3, res: [R; 3]) -> [i32; 3] {
    let k = (p - min) * inv;
    let mut c = [0i32; 3];
    for a in 0..3 {
        let r: i64 = res[a].into();
        c[a] = (k[a].floor() as i64).clamp(0, r - 1) as i32;
    }
    c
}

impl<P: Primitives> CountedTraversal for Grid<P> {
    fn traverse_with<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        mut sink: S,
    ) -> (S, TraversalCounts) {
        let mut counts = TraversalCounts::default();
        self.traverse::<COUNT, S>(q, &mut counts, &mut sink);
        (sink, counts)
    }

    fn build_info(&self) -> &AccelInfo {
        &self.info
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;
    use crate::accel::{BruteForce, Spheres, Triangles};
    use crate::geometry::Ray;

    use crate::accel::spatial::test_scenes::{hits_identical_triangles, identical_triangles, tri};

    #[test]
    fn identical_triangles_bounded_memory() {
        let g = Grid::build(identical_triangles());
        assert!(g.references() <= 1 << 20, "{} refs", g.references());
        hits_identical_triangles(&g);
    }

    #[test]
    fn flat_scene_box_and_coplanar_primitives() {
        // all triangles in z = 0: a zero-thickness scene box
        let corners: Vec<_> = (0..200)
            .map(|i| {
                let x = (i % 20) as f32;
                let y = (i / 20) as f32;
                tri([x, y, 0.0], [x + 1.0, y, 0.0], [x, y + 1.0, 0.0])
            })
            .collect();
        let prims = Triangles::from_corners(&corners);
        let g = Grid::build(prims.clone());
        assert_eq!(g.resolution()[2], 1);
        let bf = BruteForce::new(prims);
        for i in 0..400 {
            let o = Vec3::new(i as f32 * 0.05 - 0.5, (i % 13) as f32 * 0.8, 3.0);
            for d in [
                Vec3::new(0.1, 0.2, -1.0),
                -Vec3::Z,
                Vec3::new(1.0, 0.0, -0.0),
                Vec3::new(0.3, 1.0, -1.0),
            ] {
                let r = Ray::new(o, d);
                assert_eq!(
                    g.closest_hit(&r).map(|h| h.t),
                    bf.closest_hit(&r).map(|h| h.t)
                );
                // in the plane itself
                let r = Ray::new(Vec3::new(o.x, o.y, 0.0), Vec3::new(d.x, d.y, 0.0));
                assert_eq!(g.any_hit(&r), bf.any_hit(&r));
            }
        }
    }

    #[test]
    fn mailbox_tests_a_spanning_primitive_once() {
        // One huge diagonal triangle crossing the whole grid plus small ones far from
        // the test ray, which runs along the big triangle through many cells.
        let mut corners = vec![tri([0.0, 0.0, 0.0], [100.0, 100.0, 0.0], [0.0, 100.0, 1.0])];
        for i in 0..2000 {
            let p = Vec3::new(
                90.0 + (i % 10) as f32,
                (i / 10 % 10) as f32,
                (i / 100) as f32,
            );
            corners.push([p, p + Vec3::X * 0.5, p + Vec3::Y * 0.5]);
        }
        let prims = Triangles::from_corners(&corners);
        let ray = Ray::new(Vec3::new(1.0, 50.0, 0.5), Vec3::new(1.0, 0.0, 0.0));
        let on = Grid::build(prims.clone());
        let off = Grid::build_with(
            prims,
            GridOptions {
                mailbox: false,
                ..Default::default()
            },
        );
        let (h_on, c_on) = on.closest_hit_counted(&ray);
        let (h_off, c_off) = off.closest_hit_counted(&ray);
        assert_eq!(h_on, h_off);
        assert!(c_on.nodes > 10, "the ray should cross many cells: {c_on:?}");
        assert_eq!(c_on.prim_tests, 1, "{c_on:?}");
        assert!(c_off.prim_tests > 5, "{c_off:?}");
    }

    #[test]
    fn spheres_and_overlap_modes_agree() {
        let mut s = Spheres::default();
        for i in 0..500 {
            let f = i as f32;
            s.center.push(Vec3::new(
                (f * 0.37).sin() * 5.0,
                (f * 0.11).cos() * 5.0,
                (f * 0.05).sin() * 5.0,
            ));
            s.radius.push(0.1 + (i % 7) as f32 * 0.2);
        }
        let exact = Grid::build(s.clone());
        let loose = Grid::build_with(
            s.clone(),
            GridOptions {
                exact_overlap: false,
                ..Default::default()
            },
        );
        assert!(exact.references() < loose.references());
        let bf = BruteForce::new(s);
        for i in 0..2000 {
            let f = i as f32;
            let o = Vec3::new((f * 1.3).sin(), (f * 0.7).cos(), (f * 0.3).sin()) * 9.0;
            let d = Vec3::new((f * 2.1).cos(), (f * 0.9).sin(), (f * 1.7).cos());
            let r = Ray::new(o, d);
            let want = bf.closest_hit(&r).map(|h| (h.prim, h.t));
            assert_eq!(exact.closest_hit(&r).map(|h| (h.prim, h.t)), want);
            assert_eq!(loose.closest_hit(&r).map(|h| (h.prim, h.t)), want);
        }
    }
}
