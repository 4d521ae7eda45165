//! Whole-packet interval bounds: one conservative test of all of a node's children
//! for every lane of a packet group.

use super::node::EMPTY_CHILD;
use super::packet_setup::{PacketRays, far_plane, near_plane};
use crate::geometry::ROBUST_FAR_SCALE;
use crate::simd::kernels::TriGroup4;
use crate::simd::lane_ranges::lane_ranges;
use crate::simd::{F4, Lanes};

/// Trees with fewer nodes skip the whole-packet bounds: computing them costs about as
/// much as a few child tests, which a packet crossing a handful of nodes never wins
/// back (the 2-sphere, 2-triangle Whitted room traced its shadow queue 17 % slower
/// with them; the bunny's BVH4 has 8.9k nodes).
pub(super) const PACKET_BOUNDS_MIN_NODES: usize = 32;

/// Interval bounds of a packet group's rays, for a conservative test of all of a node's
/// children at once (interval arithmetic over the lanes, as in the packet traversals of
/// Wald et al. and Boulos et al.): a child that fails it is missed by every lane, so its
/// per-lane slab test is skipped. On the bunny 70 % (BVH4) and 83 % (BVH8) of the per-lane
/// child tests of primary packets hit no lane; with the bounds first, 3 % do, and primary
/// packets run 1.1x (BVH4) and 1.2x (BVH8) faster. Computing the bounds must be cheap:
/// with a scalar loop over the lanes it cost more than it saved.
///
/// Exact, not approximate: each lane computes `round(round(p - o) * inv)`; with
/// `o` in `[o_lo, o_hi]` and `inv` in `[inv_lo, inv_hi]` of one sign, rounding is
/// monotone, so that value lies between the rounded products at the interval's corners,
/// and the node test built from those corners fails only where every lane's test fails.
/// Groups with an infinite reciprocal (a zero direction component) skip the bounds.
///
/// One product per near plane (issue 12, pk18), as Embree's frustum (`node_
/// intersector_frustum.h`) takes one reciprocal per plane from the octant. Take a
/// positive reciprocal (a negative one is the mirror image): every lane's `round(p - o)`
/// is `>= x = round(p - o_near)` and its reciprocal `>= r`, the least; where `x >= 0`
/// every lane's near distance is therefore `>= round(x * r)`, the bound; where `x < 0`
/// the bound and the min of the two corner products it replaces are both `<= 0`, so the
/// entry bound (their max with the lanes' least `tmin`) is unchanged once every lane's
/// `tmin` is `>= 0` (`enabled` requires it; the triangle test clamps its `tmin` to 0).
/// The far planes keep both corner products. Tried, dropped: one far product too, its
/// bound clamped to `-0` where `y = round(p - o_far)` points back (every lane's far
/// distance is then `<= -0`, and a lane whose distance rounds to `-0` may enter), which
/// keeps the boxes behind every lane's origin that the two products cull: in
/// `packet_bounds_never_cull_a_child_a_lane_enters` 81,375 children kept for 19,583
/// entered (the test allows 3x), and bvh8-packet bunny shadow fell from 10.43 to 8.58
/// Mrays per CPU-second (`bench --modes bvh4-packet,bvh8-packet`, 5 interleaved rounds,
/// medians, load ~7: noisy, but shadow packets start on the surface, with boxes behind).
pub(super) struct PacketBounds<NL: Lanes> {
    /// The bounds, as scalars: broadcast where a node's or a leaf group's test reads
    /// them (kept as lanes of both widths, as before, they cost 34 broadcasts and stores
    /// per packet group, most never read by a packet that misses the mesh).
    b: Interval,
    /// The group's direction signs (`PacketRays::neg`).
    neg: u32,
    enabled: bool,
    lanes: std::marker::PhantomData<NL>,
}

/// A packet group's interval bounds.
#[derive(Default)]
struct Interval {
    /// Per axis: the origin bound that minimises the near-plane distance and the one that
    /// maximises the far-plane distance.
    o_near: [f32; 3],
    o_far: [f32; 3],
    /// Per axis: the lanes' reciprocal of least magnitude (near planes), and their
    /// smallest and largest far-scaled reciprocal (far planes).
    inv: [f32; 3],
    inv_far: [[f32; 2]; 3],
    /// The start of the interval of node tests, and of triangle tests (no later than 0).
    tmin: f32,
    tri_tmin: f32,
    tcull: f32,
}

impl Interval {
    /// Bits of the boxes (one per lane of `W`, given by the planes each axis enters and
    /// leaves by) that some lane of the packet group may enter after `tmin`.
    #[inline(always)]
    fn enters<W: Lanes>(&self, near: [W; 3], far: [W; 3], tmin: f32) -> u32 {
        let lo = |a: usize| (near[a] - W::splat(self.o_near[a])) * W::splat(self.inv[a]);
        let hi = |a: usize| {
            let x = far[a] - W::splat(self.o_far[a]);
            (x * W::splat(self.inv_far[a][0])).maxps(x * W::splat(self.inv_far[a][1]))
        };
        let enter = lo(0).maxps(lo(1).maxps(lo(2).maxps(W::splat(tmin))));
        let exit = hi(0).minps(hi(1).minps(hi(2).minps(W::splat(self.tcull))));
        enter.le(exit).bitmask()
    }
}

impl<NL: Lanes> PacketBounds<NL> {
    /// Bounds over the lanes of `mask`, whose intervals end at most at `tmax`.
    ///
    /// The reductions all at once (`simd::lane_ranges`) and the bounds kept as scalars
    /// (issue 12, pk19): bunny, `bench --threads 1 --reps 5 --modes
    /// bvh4-packet,bvh8-packet`, 8 interleaved rounds against the session's starting
    /// build, load 4-5, Mrays per CPU-second, min/median/max: bvh8-packet primary
    /// 24.49/34.96/37.55 -> 28.03/38.99/40.34 (+11.5 %), shadow 8.40/11.27/12.12 ->
    /// 9.09/12.09/12.90 (+7.3 %); bvh4-packet primary +7.2 %, shadow +5.7 %; diffuse
    /// level; checksums unchanged.
    #[inline(always)]
    pub(super) fn new<L: Lanes>(
        p: &PacketRays<'_, L>,
        mask: u32,
        tmax: L,
        shared: bool,
        wanted: bool,
    ) -> Self {
        let mut b = PacketBounds {
            b: Interval::default(),
            neg: p.neg,
            enabled: false,
            lanes: std::marker::PhantomData,
        };
        if !wanted || mask == 0 {
            return b;
        }
        let inv = p.inv();
        // All reductions at once: `(lo, hi)` of `tmin`/`tmax` (the least start, the
        // greatest end), the three reciprocals and, unless shared, the three origins.
        let (lo, hi, o_range): ([f32; 4], [f32; 4], [(f32, f32); 3]) = if shared {
            let (lo, hi) = lane_ranges(
                [p.tmin(), inv[0], inv[1], inv[2]],
                [tmax, inv[0], inv[1], inv[2]],
                mask,
            );
            (lo, hi, p.first_origin().map(|o| (o, o)))
        } else {
            let o = p.o();
            let (lo, hi) = lane_ranges(
                [p.tmin(), inv[0], inv[1], inv[2], o[0], o[1], o[2]],
                [tmax, inv[0], inv[1], inv[2], o[0], o[1], o[2]],
                mask,
            );
            let head = |x: [f32; 7]| [x[0], x[1], x[2], x[3]];
            (
                head(lo),
                head(hi),
                [0, 1, 2].map(|a| (lo[4 + a], hi[4 + a])),
            )
        };
        let tmin = lo[0];
        // The one-product bounds need every lane's interval to start at 0 or later.
        let mut enabled = tmin >= 0.0;
        // Tried, no win (issue 12, pk23): lowering this far end during a closest-hit
        // traversal, once every lane of the group has a hit, to the greatest lane's
        // scaled closest hit (`lane_ranges` over the lanes, after each leaf that found
        // one), so boxes and triangles behind the hits fail the whole-packet test and
        // skip their per-lane tests. Exact (the far end stays at or beyond every lane's);
        // same checksums. Bunny bvh8-packet primary 31.55/41.20/43.24 against
        // 33.54/41.90/46.92, 10^6 18.96/19.59/20.71 against 16.95/20.26/23.54 (numbers
        // and command at the frustum descent noted in `packet.rs`).
        // `round(x * scale)` is monotone in x, so the bound of the lanes' products is the
        // product of the bound (here and for the far reciprocals below).
        b.b.tcull = hi[0] * ROBUST_FAR_SCALE;
        b.b.tmin = tmin;
        // Triangles: no lane's start above zero. A hit passes its certainty test
        // (`t > δt`), so its exact distance is positive; a lane with `tmin > 0` could
        // report a hit whose exact distance lies a rounding error below `tmin`, which
        // the clamp could cull where the leaf's larger box did not.
        b.b.tri_tmin = tmin.min(0.0);
        for a in 0..3 {
            let (o_lo, o_hi) = o_range[a];
            let (i_lo, i_hi) = (lo[1 + a], hi[1 + a]);
            let (f_lo, f_hi) = (i_lo * ROBUST_FAR_SCALE, i_hi * ROBUST_FAR_SCALE);
            enabled &= f_lo.is_finite() && f_hi.is_finite();
            // A positive reciprocal: distances grow with `p - o`, so the near distance
            // is smallest at the largest origin and the far one largest at the smallest.
            let negative = p.neg >> a & 1 == 1;
            // The near reciprocal of least magnitude.
            let (o_near, o_far, i_near) = if negative {
                (o_lo, o_hi, i_hi)
            } else {
                (o_hi, o_lo, i_lo)
            };
            b.b.o_near[a] = o_near;
            b.b.o_far[a] = o_far;
            b.b.inv[a] = i_near;
            b.b.inv_far[a] = [f_lo, f_hi];
        }
        b.enabled = enabled;
        b
    }

    /// Bits of the children of a node (its `planes` and `children`) that some lane may
    /// enter (all non-empty children when the bounds are off).
    #[inline(always)]
    pub(super) fn candidates<const N: usize>(
        &self,
        planes: &[[f32; N]; 6],
        children: &[u32; N],
    ) -> u32 {
        if !self.enabled {
            return children
                .iter()
                .enumerate()
                .fold(0, |m, (c, &r)| m | u32::from(r != EMPTY_CHILD) << c);
        }
        let near = |a: usize| NL::load(&planes[near_plane(self.neg, a)]);
        let far = |a: usize| NL::load(&planes[far_plane(self.neg, a)]);
        self.b.enters(
            [near(0), near(1), near(2)],
            [far(0), far(1), far(2)],
            self.b.tmin,
        )
    }

    /// Bits of the triangles of a leaf group whose bounding box some lane may enter
    /// (all four when the bounds are off); a triangle outside them is hit by no lane.
    ///
    /// Exact: the box is the triangle's own (the min and max of its corners, exact in
    /// f32), a lane whose watertight test hits the triangle before `tmax` passes the
    /// robust slab test of any box around it, the tightest included (the property
    /// every leaf's box already relies on: a one-triangle leaf has exactly this box),
    /// and the interval test passes wherever a lane's slab test does.
    ///
    /// Measured together with the id lanes and the shorter setup of this commit (CPU
    /// time per pass of `examples/stream_profile bunny.obj bvh8-packet W`, task-clock
    /// of 41 passes minus 1, AVX-512, load ~10 on 2 cores, two runs each): primary
    /// 29.45 / 29.59 -> 26.99 / 27.38 ms (-8 %), shadow 24.23 / 24.04 -> 24.17 / 23.97
    /// ms (level: packet_any is 44 % of the shadow pass, the harness's ray set-up the
    /// rest).
    #[inline(always)]
    pub(super) fn triangle_candidates(&self, g: &TriGroup4) -> u32 {
        if !self.enabled {
            return 0b1111;
        }
        let v = |c: usize, a: usize| F4::load(&g.v[c][a]);
        // Unused lanes hold NaN corners: their bits are meaningless, and their
        // triangles are skipped by id anyway.
        // Written out per axis, not by `[0, 1, 2].map`: that was compiled as a call to
        // `core::array::try_map` per array whose 32-byte result went through the stack
        // (5.3 % of the samples of `perf record -e cpu-clock examples/stream_profile
        // 1000000 bvh8-packet primary 80`, AVX-512, quiet host, session 24).
        let lo_a = |a: usize| v(0, a).minps(v(1, a)).minps(v(2, a));
        let hi_a = |a: usize| v(0, a).maxps(v(1, a)).maxps(v(2, a));
        let lo = [lo_a(0), lo_a(1), lo_a(2)];
        let hi = [hi_a(0), hi_a(1), hi_a(2)];
        // Chosen per axis by the sign (kept in registers: taken by a plane index, the
        // six bounds were stored to the stack and read back through it).
        let bound = |a: usize, upper: bool| if upper { hi[a] } else { lo[a] };
        let near = |a: usize| bound(a, self.neg >> a & 1 == 1);
        let far = |a: usize| bound(a, self.neg >> a & 1 == 0);
        self.b.enters(
            [near(0), near(1), near(2)],
            [far(0), far(1), far(2)],
            self.b.tri_tmin,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Triangles;
    use crate::accel::bvhn::node::{NodeWidth, Width};
    use crate::accel::bvhn::packet_setup::PacketSetup;
    use crate::accel::bvhn::tree::{Bvh, Bvh4, Bvh8, Leaves};
    use crate::geometry::{Ray, RayPacket, RayQuery, intersect_triangle};
    use crate::simd::Packet;
    use glam::Vec3;

    /// Every lane's watertight test (the scalar oracle) against every leaf triangle of
    /// both widths: a triangle the whole-packet test drops is hit by no lane of the
    /// group. Returns (lane hits, triangles kept, triangles tested).
    fn check<const N: usize>(bvh: &Bvh<Triangles, N>, rays: &[Ray]) -> (u64, u64, u64)
    where
        Width<N>: NodeWidth,
    {
        let Leaves::Triangles(groups) = &bvh.leaves else {
            panic!("triangle leaves expected");
        };
        let packet = RayPacket::from_rays(rays);
        let setup = PacketSetup::<Packet>::new(&packet);
        let (mut hits, mut kept, mut tested) = (0, 0, 0);
        for g in 0..setup.groups.min(3) {
            let p = setup.group(g);
            let mask = setup.group_mask[g];
            let bounds = PacketBounds::<<Width<N> as NodeWidth>::L>::new(
                &p,
                mask,
                p.tmax(),
                setup.shared_origin,
                true,
            );
            for tri in groups {
                let cand = bounds.triangle_candidates(tri);
                for lane in 0..4 {
                    if tri.ids[lane] == u32::MAX {
                        continue;
                    }
                    tested += 1;
                    kept += u64::from(cand >> lane & 1);
                    let [a, b, c] = tri.corners(lane);
                    for i in (0..16).filter(|i| mask >> i & 1 == 1) {
                        let q = RayQuery::new(&rays[i]).expect("valid lane");
                        if intersect_triangle(&q, a, b, c, q.tmax).is_some() {
                            hits += 1;
                            assert!(cand >> lane & 1 == 1, "triangle {} culled", tri.ids[lane]);
                        }
                    }
                }
            }
        }
        (hits, kept, tested)
    }

    /// The whole-packet triangle test never drops a triangle some lane hits: packets
    /// with shared and scattered origins, narrow and wide cones, intervals starting
    /// late and ending early, against a triangle soup; and it drops most triangles.
    #[test]
    fn triangle_bounds_never_cull_a_triangle_a_lane_hits() {
        let mut s = 7u32;
        let mut r = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        let corners: Vec<[Vec3; 3]> = (0..3000)
            .map(|_| {
                let c = Vec3::new(r(), r(), r()) * 10.0;
                [
                    c,
                    c + Vec3::new(r(), r(), 0.1),
                    c + Vec3::new(0.2, r(), r()),
                ]
            })
            .collect();
        let tris = Triangles::from_corners(&corners);
        let (b4, b8) = (Bvh4::build(tris.clone()), Bvh8::build(tris));
        let (mut hits, mut kept, mut tested) = (0, 0, 0);
        for trial in 0..60 {
            let spread = [0.0, 1e-3, 0.5, 4.0][trial % 4];
            let cone = [1e-3, 0.05, 0.4][trial % 3];
            // Origins before the soup, inside it (boxes behind some lanes) and past it,
            // looking along +z and -z.
            let (z0, dz) = match trial % 5 {
                0 | 1 => (-10.0, 8.0),
                2 => (4.0, 8.0),
                3 => (4.0, -8.0),
                _ => (20.0, -8.0),
            };
            let base = Vec3::new(5.0, 5.0, z0) + Vec3::new(r(), r(), r()) * 4.0;
            let axis = (Vec3::new(r(), r(), dz) - Vec3::splat(0.5)).normalize();
            let rays: Vec<Ray> = (0..16)
                .map(|_| {
                    let o = base + Vec3::new(r(), r(), r()) * spread;
                    let d = (axis + Vec3::new(r() - 0.5, r() - 0.5, 0.0) * cone).normalize();
                    let (tmin, tmax) = match trial % 7 {
                        0 => (5.0, 14.0),
                        1 => (12.0, f32::INFINITY),
                        _ => (0.0, f32::INFINITY),
                    };
                    Ray::segment(o, d, tmin, tmax)
                })
                .collect();
            for (h, k, t) in [check(&b4, &rays), check(&b8, &rays)] {
                hits += h;
                kept += k;
                tested += t;
            }
        }
        assert!(hits > 1000, "too few hits to check: {hits}");
        assert!(
            kept < tested / 4,
            "the bounds cull little: {kept} of {tested} kept"
        );
    }
}
