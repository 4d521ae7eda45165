//! Uniform grid with 3D-DDA traversal (Amanatides & Woo, "A Fast Voxel Traversal
//! Algorithm for Ray Tracing", Eurographics 1987) and per-ray mailboxing.

use super::spatial::{
    CountedTraversal, LeafSink, Mailbox, PLANE_DISTANCE_ERROR, TraversalCounts, bounds_and_margins,
    grown, moves_along, region_margin,
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
    /// along the others; computed in f64, so any finite extent works), scaled down
    /// until the cell count is at most `max_cells``(n)`, then halved on every axis
    /// while the cell references would exceed `max(32 n, 2^20)`, which bounds memory
    /// for degenerate inputs. An explicit resolution is only halved while its cell
    /// count exceeds `MAX_CELLS`.
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

/// Memory bound on the cell count whatever the scene: the build holds two `u32` arrays
/// of one entry per cell (offsets and fill cursors), so `2^26` cells take 512 MiB.
pub const MAX_CELLS: u64 = 1 << 26;

/// Cells the automatic resolution may use for `n` primitives: `max(32 n, 4096)`
/// (the `3 cbrt(n)` rule gives at most `27 n` for a cube), at most [`MAX_CELLS`]. Before
/// issue 13 nothing bounded it: two small triangles at +-1e38 overflowed the f32
/// resolution formula to 1024^3 cells (8.4 GB).
pub fn max_cells(n: usize) -> u64 {
    (32 * n as u64).clamp(4096, MAX_CELLS)
}

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
    range_evaluations: u64,
}

/// The automatic resolution: `3 cbrt(n)` along the longest axis, proportionally fewer
/// along the others, in f64 (ratios first, so no extent overflows), then scaled down
/// uniformly until at most [`max_cells`]`(n)` cells.
fn auto_resolution(n: usize, extent: [f64; 3]) -> [u32; 3] {
    let e_max = extent.iter().copied().fold(0.0, f64::max);
    let k = 3.0 * (n as f64).cbrt();
    let mut res = [1u32; 3];
    if !(e_max > 0.0 && e_max.is_finite()) {
        return res;
    }
    for (a, r) in res.iter_mut().enumerate() {
        *r = (k * (extent[a] / e_max)).round().clamp(1.0, MAX_RES as f64) as u32;
    }
    cap_cells(res, max_cells(n))
}

/// `res` scaled down uniformly (by the cube root of the excess, then one cell at a time
/// along the longest axis) until its cell count is at most `limit`.
fn cap_cells(mut res: [u32; 3], limit: u64) -> [u32; 3] {
    let cells = |r: &[u32; 3]| r.iter().map(|&x| x as u64).fold(1u64, u64::saturating_mul);
    if cells(&res) > limit {
        let f = (limit as f64 / cells(&res) as f64).cbrt();
        res = res.map(|r| ((r as f64 * f).floor() as u32).max(1));
    }
    while cells(&res) > limit {
        let a = (0..3).max_by_key(|&a| res[a]).expect("three axes");
        res[a] -= 1;
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
        let (prim_bounds, pads, pad) = bounds_and_margins(&prims);
        let scene = prim_bounds.iter().fold(Aabb::EMPTY, |b, p| b.union(p));
        let bounds = if n == 0 {
            Aabb::EMPTY
        } else {
            // kept finite: coordinates near f32::MAX must not grow to infinity
            let g = grown(&scene, pad);
            Aabb::new(
                g.min.max(Vec3::splat(f32::MIN)),
                g.max.min(Vec3::splat(f32::MAX)),
            )
        };
        // in f64: the extent of a box from -2e38 to 2e38 overflows f32
        let extent = if n == 0 {
            [0.0; 3]
        } else {
            [0, 1, 2].map(|a| bounds.max[a] as f64 - bounds.min[a] as f64)
        };
        let mut res = match opts.resolution {
            Some(r) => cap_cells(r.map(|x| x.max(1)), MAX_CELLS),
            None => auto_resolution(n, extent),
        };

        // Per-primitive cell ranges of the grown bounds; coarsen while too many refs. A
        // pass that is going to coarsen stops as soon as it is over the budget, so
        // many large primitives (10^7 identical triangles) cost one full pass, not one
        // per halving.
        let budget = (32 * n as u64).max(1 << 20);
        let mut ranges: Vec<([i32; 3], [i32; 3])> = Vec::with_capacity(n);
        let mut range_evaluations = 0u64;
        // cell_of rounds relative to the grid's corner and extent
        let range_margin = region_margin(&bounds);
        let (cell_size, inv_cell_size) = loop {
            let cell_size = Vec3::from_array([0, 1, 2].map(|a| (extent[a] / res[a] as f64) as f32));
            let inv = Vec3::select(
                cell_size.cmpgt(Vec3::ZERO),
                Vec3::ONE / cell_size,
                Vec3::ZERO,
            );
            let may_coarsen = opts.resolution.is_none() && res != [1, 1, 1];
            ranges.clear();
            let mut total = 0u64;
            for i in 0..n {
                let b = grown(&prim_bounds[i], pads[i] + range_margin);
                let lo = cell_of(b.min, bounds.min, inv, res);
                let hi = cell_of(b.max, bounds.min, inv, res);
                total += (0..3).map(|a| (hi[a] - lo[a] + 1) as u64).product::<u64>();
                ranges.push((lo, hi));
                range_evaluations += 1;
                if may_coarsen && total > budget {
                    break;
                }
            }
            if total <= budget || !may_coarsen {
                break (cell_size, inv);
            }
            res = res.map(|r| r.div_ceil(2));
        };
        let res_i = res.map(|r| r as i32);
        let cells = res.iter().map(|&r| r as usize).product::<usize>();

        // Two passes: count, prefix sum, fill (the overlap test runs in both).
        let cell_box = |c: [i32; 3], pad: f32| {
            let lo = bounds.min + Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * cell_size;
            let cell = Aabb::new(lo, lo + cell_size);
            grown(&cell, pad + region_margin(&cell))
        };
        let for_each_cell = |i: usize, f: &mut dyn FnMut(usize)| {
            let (lo, hi) = ranges[i];
            let single = lo == hi;
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        if single
                            || !opts.exact_overlap
                            || prims.overlaps_box(i, &cell_box([x, y, z], pads[i]))
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
            range_evaluations,
        }
    }

    /// Work of choosing the resolution: primitive bounds mapped to cell ranges, over
    /// all coarsening passes (`n` when the first resolution fits the budget).
    pub fn range_evaluations(&self) -> u64 {
        self.range_evaluations
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
    ///
    /// Carried in f64 from the exact f32 inputs (origin, direction, the f32 cell planes
    /// the build assigned primitives against): the entry, the start cell and every
    /// boundary distance `(x - o) / d` (computed freshly each step, no accumulation)
    /// are within `2^-51` of the distance from the origin, so the walk follows the exact
    /// ray to within a small fraction of the cells' assignment margin (`32 u` of a
    /// cell's extent, [`region_margin`]) for origins up to about `2^32` cell sizes away
    /// (docs/robustness.md, "Assignment margins"). In f32 the entry point `o + t d`
    /// alone was off by `u |o|`, several cells for `|o| ~ 1e8`.
    #[inline(always)]
    fn traverse<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        counts: &mut TraversalCounts,
        sink: &mut S,
    ) {
        let o = [0, 1, 2].map(|a| q.origin[a] as f64);
        let d = [0, 1, 2].map(|a| q.dir[a] as f64);
        let moving = [0, 1, 2].map(|a| moves_along(q, a));
        // Clip to the grid box in f64 (parallel axes: inside the slab or a miss).
        let (mut t0, mut t1) = (q.tmin as f64, q.tmax as f64);
        for a in 0..3 {
            let (lo, hi) = (self.bounds.min[a] as f64, self.bounds.max[a] as f64);
            if moving[a] {
                let (ta, tb) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            } else if !(lo <= o[a] && o[a] <= hi) {
                return;
            }
        }
        // a NaN bound (never expected) counts as a miss, as `!(t0 <= t1)` would
        if t0.partial_cmp(&t1).is_none_or(|o| o.is_gt()) {
            return;
        }
        let mut cell = [0i32; 3];
        let mut step = [0i32; 3];
        let mut next_t = [f64::INFINITY; 3];
        for a in 0..3 {
            let p = if moving[a] { o[a] + t0 * d[a] } else { o[a] };
            cell[a] = self.start_cell(a, p);
            if moving[a] {
                step[a] = if q.dir[a] > 0.0 { 1 } else { -1 };
                next_t[a] = self.boundary_t(o[a], d[a], a, cell[a], step[a]);
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
            // the ray's own tmax) is at or before the next cell's entry, lowered by
            // PLANE_DISTANCE_ERROR: the f32 `t` of a hit in a later cell is rounded by a
            // few `u` of the distance (the primitive test's error), so a hit whose exact
            // `t` is beyond the boundary may still compare nearer than the one kept.
            let axis = if next_t[0] <= next_t[1] && next_t[0] <= next_t[2] {
                0
            } else if next_t[1] <= next_t[2] {
                1
            } else {
                2
            };
            let exit = next_t[axis];
            let exit_lb = exit - PLANE_DISTANCE_ERROR as f64 * exit.abs();
            if sink.tmax() as f64 <= exit_lb || step[axis] == 0 {
                return;
            }
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= self.res[axis] {
                return;
            }
            next_t[axis] = self.boundary_t(o[axis], d[axis], axis, cell[axis], step[axis]);
        }
    }

    /// Position of plane `k` along `a`, exactly as the build's cell boxes place it (f32).
    #[inline(always)]
    fn plane(&self, a: usize, k: i32) -> f64 {
        (self.bounds.min[a] + k as f32 * self.cell_size[a]) as f64
    }

    /// The cell along `a` whose planes enclose coordinate `p` (clamped to the grid): a
    /// first guess from the cell size, corrected against the planes themselves.
    #[inline(always)]
    fn start_cell(&self, a: usize, p: f64) -> i32 {
        let last = self.res[a] - 1;
        let guess = (p - self.bounds.min[a] as f64) * self.inv_cell_size[a] as f64;
        // NaN casts to 0; the clamp keeps it in the grid
        let mut k = (guess.floor() as i64).clamp(0, last as i64) as i32;
        while k > 0 && p < self.plane(a, k) {
            k -= 1;
        }
        while k < last && p >= self.plane(a, k + 1) {
            k += 1;
        }
        k
    }

    /// Distance (f64) to the boundary of `cell` the ray leaves through along `a`,
    /// computed from the origin each time (no accumulated increments).
    #[inline(always)]
    fn boundary_t(&self, o: f64, d: f64, a: usize, cell: i32, step: i32) -> f64 {
        let k = if step > 0 { cell + 1 } else { cell };
        (self.plane(a, k) - o) / d
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
    fn huge_extents_get_a_small_bounded_resolution() {
        // Before issue 13 the f32 formula overflowed (3 cbrt(2) * 2e38 = inf) and clamped
        // to 1024^3 cells.
        let res = auto_resolution(2, [2e38; 3]);
        let cells: u64 = res.iter().map(|&r| r as u64).product();
        assert!(cells <= max_cells(2), "{res:?}");
        assert_eq!(res, [4, 4, 4]);
        // a flat, wide box: proportional, and capped by the primitive count
        let res = auto_resolution(1000, [f32::MAX as f64 * 2.0, 1.0, 0.0]);
        assert_eq!(res, [30, 1, 1]);
        let res = auto_resolution(100_000_000, [1.0; 3]);
        let cells: u64 = res.iter().map(|&r| r as u64).product();
        assert!(cells <= MAX_CELLS, "{res:?}");
        // an explicit resolution is capped by memory
        let res = cap_cells([u32::MAX; 3], MAX_CELLS);
        let cells: u64 = res.iter().map(|&r| r as u64).product();
        assert!(cells <= MAX_CELLS && cells > MAX_CELLS / 2, "{res:?}");
    }

    #[test]
    fn far_apart_triangles_build_small_and_hit() {
        // A unit triangle at the origin with a small triangle at +-1e38 (extent 2e38) or
        // at +-2e38 (the extent, 4e38, overflows f32). Before issue 13: 1024^3 cells.
        let unit = tri([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        for at in [1e38f32, 2e38, -2e38] {
            let far = |c: f32| {
                let p = Vec3::splat(c);
                [
                    p,
                    p + Vec3::new(c * 1e-3, 0.0, 0.0),
                    p + Vec3::new(0.0, c * 1e-3, 0.0),
                ]
            };
            let prims = Triangles::from_corners(&[unit, far(at), far(-at)]);
            let g = Grid::build(prims.clone());
            assert!(g.info.nodes as u64 <= max_cells(3), "{:?}", g.resolution());
            let bf = BruteForce::new(prims);
            let down = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
            assert_eq!(g.closest_hit(&down).map(|h| (h.prim, h.t)), Some((0, 1.0)));
            // Rays at the far triangles agree with brute force (which finds no hit: the
            // f32 triangle test overflows on products of coordinates near 1e38).
            for c in [at, -at] {
                let target = Vec3::new(c + c * 2e-4, c + c * 2e-4, c);
                for o in [Vec3::new(0.3, 0.2, 0.1), target + Vec3::Z * c.abs() * 1e-3] {
                    let r = Ray::new(o, (target - o).normalize());
                    assert_eq!(
                        g.closest_hit(&r).map(|h| (h.prim, h.t)),
                        bf.closest_hit(&r).map(|h| (h.prim, h.t)),
                        "{o} -> {target}"
                    );
                    assert_eq!(g.any_hit(&r), bf.any_hit(&r));
                }
            }
        }
    }

    #[test]
    fn identical_triangles_choose_resolution_in_about_one_pass() {
        // Every halving pass used to map all n primitives to cell ranges (4 passes here,
        // 10 at n = 10^7); a pass over the budget now stops as soon as it is over.
        let g = Grid::build(identical_triangles());
        let n = 10_000u64;
        assert!(
            g.range_evaluations() < n + n / 2,
            "{} range evaluations for {n} primitives",
            g.range_evaluations()
        );
        hits_identical_triangles(&g);
    }

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
