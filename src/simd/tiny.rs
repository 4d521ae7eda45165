//! Brute-force lane kernels for scenes of a handful of primitives
//! ([`crate::accel::TinyScene`]): every ray of a lane group against every primitive,
//! with no tree, no slab tests and no traversal stack.
//!
//! The rays of a group share the watertight test's axis permutation (the dominant
//! direction axis and its sign, [`shear_key`]), so the triangle test is
//! [`triangle_packet_corners`] as the BVH packet kernels run it, with lanes whose edge function
//! is within its error bound of zero redone by the scalar test ([`intersect_triangle`],
//! with its f64 fallback); the sphere test is [`sphere_lanes`], the lane twin of
//! `intersect_sphere`. Both give the scalar answers bit for bit, and primitives are
//! tested in index order with the same strict `t < tmax` update as the brute-force
//! structure, so a lane's closest hit is `BruteForce::closest_hit`'s, ties included.

use super::kernels::{PacketShear, RayLanes, sphere_lanes, triangle_packet_corners};
use super::shadow_cull::AxisPlane;
use super::{Lanes, PACKET_WIDTH, Packet};
use crate::geometry::{Ray, RayQuery, dominant_axis, intersect_triangle};
use glam::Vec3;

/// Lanes of one group.
pub type TinyLanes = Packet;
/// Rays per lane group.
pub const TINY_WIDTH: usize = PACKET_WIDTH;

/// Which of the six axis permutations of the watertight test a ray uses: its dominant
/// axis `kz` (as `RayQuery::new` picks it) times two, plus one where `d[kz] < 0`.
/// Invalid rays (`!Ray::is_valid`) have no key: they hit nothing.
#[inline]
pub fn shear_key(r: &Ray) -> Option<usize> {
    if !r.is_valid() {
        return None;
    }
    let kz = dominant_axis(r.dir);
    Some(kz * 2 + (r.dir[kz] < 0.0) as usize)
}

/// The bits of the lanes of `lanes` (interval ends `tmax`) that hold a valid ray
/// (`Ray::is_valid` in lanes: finite origin and direction, a non-zero direction, an
/// interval with no NaN and `tmin <= tmax`): what [`uniform_shear_key`] and
/// [`lane_shear_keys`] both start from.
#[inline(always)]
fn valid_lanes(lanes: &RayLanes<TinyLanes>, tmax: TinyLanes) -> u32 {
    let [ox, oy, oz] = lanes.o;
    let [dx, dy, dz] = lanes.d;
    let finite = ox.is_finite() & oy.is_finite() & oz.is_finite();
    let finite = finite & dx.is_finite() & dy.is_finite() & dz.is_finite();
    let zero = TinyLanes::splat(0.0);
    let null = dx.simd_eq(zero) & dy.simd_eq(zero) & dz.simd_eq(zero);
    // `simd_le` is false for a NaN on either side, as `!is_nan && tmin <= tmax`.
    (finite & lanes.tmin.simd_le(tmax)).to_bitmask() & !null.to_bitmask()
}

/// The [`shear_key`] shared by all [`TINY_WIDTH`] rays in `lanes` (interval ends
/// `tmax`), or `None` when a ray is invalid (`Ray::is_valid` in lanes: finite origin
/// and direction, a non-zero direction, an interval with no NaN and `tmin <= tmax`)
/// or two keys differ. `dominant_axis` in lanes: x where |x| is at least |y| and |z|,
/// else y where |y| >= |z|, else z.
#[inline(always)]
pub fn uniform_shear_key(lanes: &RayLanes<TinyLanes>, tmax: TinyLanes) -> Option<usize> {
    let [dx, dy, dz] = lanes.d;
    let all = (1u32 << TINY_WIDTH) - 1;
    if valid_lanes(lanes, tmax) != all {
        return None;
    }
    let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
    let x = (ax.simd_ge(ay) & ax.simd_ge(az)).to_bitmask();
    let y = !x & ay.simd_ge(az).to_bitmask() & all;
    let (kz, d) = if x == all {
        (0, dx)
    } else if y == all {
        (1, dy)
    } else if x | y == 0 {
        (2, dz)
    } else {
        return None;
    };
    match d.to_bitmask() {
        // `d[kz] < 0`: the sign bit of a non-zero lane (the dominant component of a
        // non-zero direction is not zero, so -0.0 cannot occur).
        0 => Some(kz * 2),
        m if m == all => Some(kz * 2 + 1),
        _ => None,
    }
}

/// Per lane the [`shear_key`] of the rays in `lanes` (interval ends `tmax`), as one
/// bitmask per key (`keys[k]` has bit `i` where lane `i`'s key is `k`); lanes holding
/// an invalid ray (`Ray::is_valid` in lanes, as [`uniform_shear_key`]) are in no mask.
/// For lanes that may mix keys (the light samples of one shading point seen across an
/// axis diagonal); a caller tests each non-empty mask as one group.
#[inline(always)]
pub fn lane_shear_keys(lanes: &RayLanes<TinyLanes>, tmax: TinyLanes) -> [u32; 6] {
    let [dx, dy, dz] = lanes.d;
    let zero = TinyLanes::splat(0.0);
    let valid = valid_lanes(lanes, tmax);
    let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
    let x = (ax.simd_ge(ay) & ax.simd_ge(az)).to_bitmask() & valid;
    let y = !x & ay.simd_ge(az).to_bitmask() & valid;
    let z = !x & !y & valid;
    // `d[kz] < 0`, false for -0.0 as in `RayQuery::new`.
    let neg = |d: TinyLanes| d.simd_lt(zero).to_bitmask();
    let (nx, ny, nz) = (neg(dx), neg(dy), neg(dz));
    [x & !nx, x & nx, y & !ny, y & ny, z & !nz, z & nz]
}

/// Up to [`TINY_WIDTH`] valid rays of the same [`shear_key`], as lanes.
pub struct TinyGroup {
    pub lanes: RayLanes<TinyLanes>,
    pub tmax: TinyLanes,
    pub shear: PacketShear<TinyLanes>,
    /// Bits of the lanes holding a ray.
    pub mask: u32,
}

impl TinyGroup {
    /// The group of the rays `rays[ids[i]]` (at most [`TINY_WIDTH`], all valid, all
    /// of key `key`), gathered straight into lanes.
    #[inline]
    pub fn new(rays: &[Ray], ids: &[u32], key: usize) -> TinyGroup {
        debug_assert!(ids.len() <= TINY_WIDTH);
        let (lanes, tmax) = RayLanes::gather(ids.iter().map(|&id| {
            let r = &rays[id as usize];
            debug_assert_eq!(shear_key(r), Some(key));
            r
        }));
        Self::from_lanes(key, lanes, tmax, ((1u64 << ids.len()) - 1) as u32)
    }

    /// The group of the lanes `mask` of rays already in `lanes` (interval ends
    /// `tmax`), all valid and of key `key`; the other lanes are ignored.
    #[inline(always)]
    pub fn from_lanes(
        key: usize,
        lanes: RayLanes<TinyLanes>,
        tmax: TinyLanes,
        mask: u32,
    ) -> TinyGroup {
        let RayLanes { o, d, tmin } = lanes;
        // The permutation of `RayQuery::new`: kx, ky follow kz, swapped when d[kz] < 0.
        let kz = key / 2;
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if key % 2 == 1 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = TinyLanes::splat(1.0) / d[kz];
        TinyGroup {
            lanes: RayLanes { o, d, tmin },
            tmax,
            shear: PacketShear::new(&d, sz, (kx, ky, kz)),
            mask,
        }
    }

    /// The scalar query of lane `i` (a valid ray), rebuilt from the lanes, which hold
    /// the ray's fields exactly (`RayQuery::new` reads origin, direction and interval;
    /// the time does not enter the triangle test).
    fn query(&self, i: usize) -> RayQuery {
        let at = |a: &[TinyLanes; 3]| {
            Vec3::new(a[0].to_array()[i], a[1].to_array()[i], a[2].to_array()[i])
        };
        let ray = Ray {
            origin: at(&self.lanes.o),
            dir: at(&self.lanes.d),
            tmin: self.lanes.tmin.to_array()[i],
            tmax: self.tmax.to_array()[i],
            time: 0.0,
        };
        RayQuery::new(&ray).expect("a tiny group holds valid rays only")
    }

    /// The packet triangle test of the group's lanes in `live` against `corners`.
    #[inline(always)]
    fn triangle(
        &self,
        corners: &[Vec3; 3],
        tmax: TinyLanes,
        live: u32,
    ) -> (TinyLanes, TinyLanes, TinyLanes, u32, u32) {
        let l = &self.lanes;
        triangle_packet_corners(&l.o, l.tmin, &self.shear, corners, tmax, live)
    }

    /// Closest hits over `triangles` then `spheres` (index order, strict `t < tmax`),
    /// as [`TinyHits`]: triangle `k` is prim `k`, sphere `k` is prim `triangles.len() + k`.
    ///
    /// Tried and not kept: the group as two eight-lane halves (the same loop over
    /// `f32x8` lanes, lanes `0..8` then `8..16`, a half with no lane in the mask
    /// skipped), so that the state kept across the primitives (hit `t, u, v`, primitive,
    /// the rays and shear constants: 14 values, 28 YMM registers at sixteen lanes) fits
    /// the sixteen YMM registers of AVX2. The code shrank (1029 instructions, 111 of
    /// them YMM stack moves, against 1620 and 289) but ran more instructions: every
    /// half repeats the per-primitive scalar work (corner reads, splats, the hit-bit
    /// tests and the early exit). Callgrind, whitted_base, 1 thread: this function
    /// 139.1 M -> 164.1 M instructions (1024x768); with the corners permuted once per
    /// group into the test's axis order (no `Vec3` index by a run-time axis) 35.4 M ->
    /// 46.8 M (512x384; 51.5 M unpermuted); the trace stage's time rose too (7
    /// interleaved runs, medians 34 -> 46 ms, machine loaded ~9 on 2 cores). Images
    /// were byte-identical and a test matched both forms lane for lane.
    pub fn closest(&self, triangles: &[[Vec3; 3]], spheres: &[(Vec3, f32)]) -> TinyHits {
        let mut tmax = self.tmax;
        let zero = TinyLanes::splat(0.0);
        let (mut tu, mut tv) = (zero, zero);
        // The primitive index of each lane's hit, as f32 bits selected like `t`, `u`
        // and `v` (one blend per primitive where a store per hit lane was 6 % of this
        // function's samples, whitted_base aa3x3, perf).
        let index = |k: usize| TinyLanes::splat(f32::from_bits(k as u32));
        let mut prim = TinyLanes::splat(f32::from_bits(u32::MAX));
        let mut hit = 0u32;
        let (o, d) = (&self.lanes.o, &self.lanes.d);
        // The last axis plane met and its lanes to test (a quad's second triangle
        // shares its first one's plane).
        let mut last: Option<(AxisPlane, u32)> = None;
        for (k, corners) in triangles.iter().enumerate() {
            // An axis-aligned triangle (the Whitted floor) is not tested for the lanes
            // leaving its plane from their origin's side (`AxisPlane`: no hit there):
            // primary rays above the horizon, rays reflected off the floor.
            let live = match AxisPlane::of(corners) {
                Some(p) => match last {
                    Some((q, live)) if q == p => live,
                    _ => {
                        let live = self.mask & !p.leaving_lanes(o, d, self.mask);
                        last = Some((p, live));
                        live
                    }
                },
                None => self.mask,
            };
            if live == 0 {
                continue;
            }
            let (t, u, v, mut bits, edge) = self.triangle(corners, tmax, live);
            let (mut t, mut u, mut v) = (t, u, v);
            if edge != 0 {
                let (mut ta, mut ua, mut va) = (t.to_array(), u.to_array(), v.to_array());
                let tm = tmax.to_array();
                for_each_bit(edge, |i| {
                    let q = self.query(i);
                    if let Some(h) =
                        intersect_triangle(&q, corners[0], corners[1], corners[2], tm[i])
                    {
                        (ta[i], ua[i], va[i]) = (h.t, h.u, h.v);
                        bits |= 1 << i;
                    }
                });
                (t, u, v) = (
                    TinyLanes::from_array(ta),
                    TinyLanes::from_array(ua),
                    TinyLanes::from_array(va),
                );
            }
            if bits != 0 {
                let sel = TinyLanes::mask_from_bits(bits);
                tmax = TinyLanes::select(sel, t, tmax);
                tu = TinyLanes::select(sel, u, tu);
                tv = TinyLanes::select(sel, v, tv);
                prim = TinyLanes::select(sel, index(k), prim);
                hit |= bits;
            }
        }
        for (k, &(center, radius)) in spheres.iter().enumerate() {
            let (t, bits) = sphere_lanes(&self.lanes, center, radius, tmax, self.mask);
            if bits != 0 {
                let sel = TinyLanes::mask_from_bits(bits);
                tmax = TinyLanes::select(sel, t, tmax);
                tu = TinyLanes::select(sel, zero, tu);
                tv = TinyLanes::select(sel, zero, tv);
                prim = TinyLanes::select(sel, index(triangles.len() + k), prim);
                hit |= bits;
            }
        }
        TinyHits {
            t: tmax.to_array(),
            u: tu.to_array(),
            v: tv.to_array(),
            prim: prim.to_array().map(f32::to_bits),
            hit,
        }
    }

    /// Occlusion by `triangles` (bits of the lanes blocked by any of them).
    pub fn any_triangle(&self, triangles: &[[Vec3; 3]]) -> u32 {
        let mut blocked = 0u32;
        for corners in triangles {
            let live = self.mask & !blocked;
            if live == 0 {
                break;
            }
            blocked |= self.triangle_blocks(corners, live);
        }
        blocked
    }

    /// Occlusion of the lanes in `live` by one triangle.
    #[inline(always)]
    pub fn triangle_blocks(&self, corners: &[Vec3; 3], live: u32) -> u32 {
        let (_, _, _, mut blocked, edge) = self.triangle(corners, self.tmax, live);
        if edge != 0 {
            let tm = self.tmax.to_array();
            for_each_bit(edge, |i| {
                let q = self.query(i);
                if intersect_triangle(&q, corners[0], corners[1], corners[2], tm[i]).is_some() {
                    blocked |= 1 << i;
                }
            });
        }
        blocked
    }

    /// The lanes of `live` for which the triangle test against `corners` cannot report
    /// a hit because the triangle lies beyond the end of their segment: every corner's
    /// depth in the test's sheared space, `sz (corner[kz] - o[kz])` (the test's `az`,
    /// `bz`, `cz`, computed by the same f32 operations), is at least `tmax` with a
    /// margin of `2^-20` relative. Skipping them gives the test's own answers
    /// ([`BEYOND_MARGIN`] says why). The light samples of a quad light seen along its
    /// normal's axis: the segment stops short of the light (`spawn_ray_to`), and each
    /// sample's lanes would otherwise run the full test on both of the light's triangles.
    #[inline(always)]
    pub fn beyond(&self, corners: &[Vec3; 3], live: u32) -> u32 {
        let kz = self.shear.kz;
        // Negated twice, as in the triangle test (`triangle_packet`): the same depth but
        // for the sign of a zero, which the comparison does not see.
        let depth = |c: &Vec3| self.shear.neg_sz * (self.lanes.o[kz] - TinyLanes::splat(c[kz]));
        // Per corner, as `fl(x (1 - 2^-20))` is monotone in `x`: the least depth passes
        // where all do. A NaN depth fails its comparison and keeps the lane.
        let margin = TinyLanes::splat(BEYOND_MARGIN);
        let far = |c: &Vec3| (depth(c) * margin).simd_ge(self.tmax);
        (far(&corners[0]) & far(&corners[1]) & far(&corners[2])).to_bitmask() & live
    }

    /// Occlusion of the lanes in `live` by `spheres`.
    pub fn any_sphere(&self, spheres: &[(Vec3, f32)], live: u32) -> u32 {
        let mut blocked = 0u32;
        for &(center, radius) in spheres {
            let rest = live & !blocked;
            if rest == 0 {
                break;
            }
            blocked |= sphere_lanes(&self.lanes, center, radius, self.tmax, rest).1;
        }
        blocked
    }
}

/// `1 - 2^-20`: the factor of [`TinyGroup::beyond`]'s depth test.
///
/// Why a lane with `fl(m · BEYOND_MARGIN) >= tmax` (`m` the least of the computed
/// corner depths `az, bz, cz`) gets no hit from the watertight test, the packet one or
/// the scalar fallback (`intersect_triangle`, whose f64 edges end in the same f32
/// `t` formula): a hit needs the three edge values `u, v, w` of one sign (or zero)
/// and `t = fl(fl(fl(fl(u az) + fl(v bz)) + fl(w cz)) / fl(fl(u + v) + w)) < tmax`.
/// With `u, v, w >= 0` (the other sign is the same with both signs flipped) every term
/// of both sums is non-negative, so with `u_r = 2^-24` (no underflow, below) the
/// numerator is at least `(u az + v bz + w cz)(1 - u_r)^3 >= m (u + v + w)(1 - u_r)^3`,
/// the denominator at most `(u + v + w)(1 + u_r)^2`, and the rounded quotient at least
/// `m (1 - u_r)^4 / (1 + u_r)^2 >= m (1 - 6 u_r)`. The test computes
/// `fl(m (1 - 16 u_r)) <= m (1 - 16 u_r)(1 + u_r) < m (1 - 6 u_r) <= t`, so
/// `t >= tmax`: no hit. `m > 0` follows from the test where `tmax > 0`; where
/// `tmax = 0` no `t` lies in `(0, tmax)` anyway. Underflow: a hit also needs
/// `t > δt >= 3 δE maxZt |1/det|`, with `δE` at least `2^-27` of the f32 edge bound
/// (`2 err::EDGE max_x max_y` and more), so the edge values of a hit sum to far above
/// the subnormal range wherever the triangle's sheared coordinates are above about
/// `2^-30` of the scene's unit; the relative bounds then hold for the largest term and
/// the subnormal rest changes the sums by at most `2^-149` each.
pub const BEYOND_MARGIN: f32 = 1.0 - 1.0 / (1u32 << 20) as f32;

/// Per-lane closest hits of a [`TinyGroup`].
pub struct TinyHits {
    pub t: [f32; TINY_WIDTH],
    pub u: [f32; TINY_WIDTH],
    pub v: [f32; TINY_WIDTH],
    pub prim: [u32; TINY_WIDTH],
    pub hit: u32,
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// A triangle's plane, to skip the triangle test for rays that cannot hit it: a ray
/// whose origin lies on the plane or on one side of it and whose direction leaves that
/// side has its exact plane crossing at `t* <= 0`, and the watertight test reports no
/// hit there (it accepts only `t > δt`, `δt` the error bound of `t`: pbrt-v4's
/// conservative `t > 0`, [`intersect_triangle`] and its lane twins, the scalar f64 edge
/// fallback included). So skipping those lanes gives the test's own answers.
///
/// The side is decided in f64 from the f32 corners and origin: exactly where every
/// operation of `n · (o - v0)` is checked exact (an origin on the plane of an
/// axis-aligned floor, the common case: no offset along an exactly axis-aligned
/// normal), else only when the value clears its error bound by a factor of 1000
/// (`1e-12` of the sum of the magnitudes of its terms, against f64 rounding of
/// ~`1e-15`). The direction's side is decided per lane in f32 with a margin of
/// `1e-5` of the same kind of sum (its rounding is below `3e-7` of it).
///
/// Measured (perf, whitted_area64 512x384, 1 thread): with the light samples of one
/// shading point tested in lanes, `TinyGroup::any_triangle` was 29 % of the frame,
/// every floor sample running the whole test (edge functions, `t` and its bound) on
/// both floor triangles to be rejected by `t > δt`.
#[derive(Clone, Copy, Debug)]
pub struct TrianglePlane {
    v0: Vec3,
    /// `e1 × e2` (the edges from `v0`) in f64, and whether each component is exact.
    n: [f64; 3],
    n_exact: bool,
    /// `|e1_j e2_k| + |e1_k e2_j|` per component: a bound on the terms of `n`.
    terms: [f64; 3],
    n32: [f32; 3],
    terms32: [f32; 3],
    /// `(k, sign)` where the plane is one of constant coordinate `k` for
    /// [`side`](Self::side) (see [`axis_side`](Self::axis_side)): `sign` that of `n_k`.
    axis: Option<(usize, f32)>,
}

/// `a - b` and whether it is exact (Knuth's TwoSum error is zero).
#[inline]
fn sub_exact(a: f64, b: f64) -> (f64, bool) {
    add_exact(a, -b)
}

#[inline]
fn add_exact(a: f64, b: f64) -> (f64, bool) {
    let s = a + b;
    let bb = s - a;
    let err = (a - (s - bb)) + (b - bb);
    (s, err == 0.0)
}

/// `a b` and whether it is exact (the fused residual is zero).
#[inline]
fn mul_exact(a: f64, b: f64) -> (f64, bool) {
    let p = a * b;
    (p, a.mul_add(b, -p) == 0.0 && p.is_finite())
}

/// `(k, sign(n_k))` where `side_f64` of any f32 origin with `origin_k != v0_k` is
/// `Some(sign(n_k))` above `v0_k` and `Some(-sign(n_k))` below (and, level with it,
/// what `axis_side` says: `w_k = 0`, every product `±0` and exact, so the flags are
/// `n_exact` and the two other differences', `s = ±0` and the margin `0`): the other two components
/// of `n` and of `terms` are zero, and `n_k` is finite with `2^-800 < |n_k| < 2^800` and
/// `|n_k| >= 2e-12 terms_k`.
///
/// Proof (`side_f64` step by step): the two other components give `w` finite (f32
/// differences), products `0 · w = ±0` (exact, finite), sums `s ± 0 = s` (exact) and
/// bound terms `0 · |w| = 0`. For `k`: `w_k`, the f64 difference of two distinct f32,
/// is nonzero with the sign of `origin_k - v0_k` and `2^-149 <= |w_k| < 2^129`, so
/// `p = n_k w_k` rounds to a normal f64 in `[2^-949, 2^929]` of sign `sign(n_k)
/// sign(w_k)`; added to `±0` it is `s`. Exact or not, the answer is that sign: where the
/// exactness flags hold `side_f64` returns it; elsewhere it compares `s` with
/// `margin = 1e-12 terms_k |w_k|` (three roundings, each at most `1 + 2^-53`, none
/// overflowing: `terms_k <= |n_k| / 2e-12 < 2^840`), and `|s|` is at least
/// `|n_k| |w_k| (1 - 2^-53)`, so at least `2e-12 terms_k |w_k| (1 - 2^-53)`, more than
/// `margin` (or `margin = 0 < |s|`). A test compares
/// both on planes of every axis and origins near, far and level.
fn axis_of(n: &[f64; 3], terms: &[f64; 3]) -> Option<(usize, f32)> {
    let k = (0..3).find(|&k| n[k] != 0.0)?;
    let others_zero = (0..3).all(|j| j == k || (n[j] == 0.0 && terms[j] == 0.0));
    let a = n[k].abs();
    let range = a > (-800.0f64).exp2() && a < 800.0f64.exp2();
    (others_zero && range && a >= 2e-12 * terms[k]).then_some((k, n[k].signum() as f32))
}

impl TrianglePlane {
    pub fn new(c: &[Vec3; 3]) -> TrianglePlane {
        let mut exact = true;
        let mut diff = |p: Vec3| {
            let mut e = [0.0; 3];
            for (k, e) in e.iter_mut().enumerate() {
                let (d, x) = sub_exact(p[k] as f64, c[0][k] as f64);
                exact &= x;
                *e = d;
            }
            e
        };
        let (e1, e2) = (diff(c[1]), diff(c[2]));
        let mut n = [0.0; 3];
        let mut terms = [0.0; 3];
        for (k, (n, t)) in n.iter_mut().zip(&mut terms).enumerate() {
            let (j, l) = ((k + 1) % 3, (k + 2) % 3);
            let (p, x) = mul_exact(e1[j], e2[l]);
            let (q, y) = mul_exact(e1[l], e2[j]);
            let (d, z) = sub_exact(p, q);
            exact &= x && y && z;
            *n = d;
            *t = p.abs() + q.abs();
        }
        TrianglePlane {
            v0: c[0],
            n,
            n_exact: exact,
            terms,
            n32: n.map(|x| x as f32),
            terms32: terms.map(|x| x as f32),
            axis: axis_of(&n, &terms),
        }
    }

    /// Whether `other` is the same plane as `self` for [`side`](Self::side) and
    /// [`leaving`](Self::leaving): the same `v0` and the same values of `n` and its term
    /// bounds (in f64 and f32). Both functions read `n` only through products summed and
    /// compared strictly with zero or a margin, where a zero's sign changes nothing, so
    /// equal values give equal answers (two triangles of one quad share their plane).
    pub fn same_plane(&self, other: &TrianglePlane) -> bool {
        self.v0 == other.v0
            && self.n == other.n
            && self.n_exact == other.n_exact
            && self.terms == other.terms
            && self.n32 == other.n32
            && self.terms32 == other.terms32
    }

    /// Whether the plane cull ([`leaving`](Self::leaving)) may skip any segment from
    /// about `from` to a point of the convex hull of `to`: false where `from` is off
    /// the plane and every point of `to` lies towards the plane from it or level (all
    /// such segments approach the plane: a quad light's own plane, seen from below it).
    /// A heuristic in f32, which only decides whether the cull is tried: skipping the
    /// cull leaves the triangle test to answer, which it does exactly.
    pub fn may_cull(&self, from: Vec3, to: &[Vec3]) -> bool {
        let n = Vec3::from_array(self.n32);
        let at = n.dot(from - self.v0);
        at == 0.0 || !to.iter().all(|&c| n.dot(c - from) * at.signum() <= 0.0)
    }

    /// [`may_cull`](Self::may_cull) of every lane's `from` at once: bit `i` for lane
    /// `i`, its answer (the same f32 operations per lane; `at.signum()` as a select by
    /// the sign bit, and a NaN `at`, whose products are NaN there, failing every
    /// corner's comparison). A pack of shading points (`integrator::area_light`) asks for
    /// its points together.
    ///
    /// Measured: called point by point, `may_cull` and its caller
    /// (`LaneOccluders::spheres_near_points`) were ~12 % of `shade_quads_packed`'s perf
    /// samples on dof_area 960x720 (1 thread): every point below the light asks for
    /// the light's own plane, which it never culls.
    #[inline(always)]
    pub fn may_cull_lanes(&self, from: super::lanes3::V3, to: &[Vec3]) -> u32 {
        use super::lanes3::V3;
        type L = Packet;
        let n = V3::splat(Vec3::from_array(self.n32));
        let at = n.dot(from.minus(V3::splat(self.v0)));
        let zero = L::splat(0.0);
        let sign = <L as Lanes>::select(
            <L as Lanes>::mask_from_bits(<L as Lanes>::sign_bits(at)),
            L::splat(-1.0),
            L::splat(1.0),
        );
        // (A NaN `at` makes every product NaN there: no corner compares.)
        let number = <L as Lanes>::bitmask(<L as Lanes>::eq(at, at));
        let mut all = u32::MAX;
        for &c in to {
            let p = n.dot(V3::splat(c).minus(from)) * sign;
            all &= <L as Lanes>::bitmask(<L as Lanes>::le(p, zero)) & number;
        }
        let on = <L as Lanes>::bitmask(<L as Lanes>::eq(at, zero));
        (on | !all) & (u32::MAX >> (32 - PACKET_WIDTH))
    }

    /// The side of the plane `origin` lies on: `Some(1.0)` on the side `n` points to,
    /// `Some(-1.0)` on the other, `Some(0.0)` exactly on it; `None` where the f64 value
    /// is neither exact nor clear of its bound.
    ///
    /// A plane of constant coordinate (`axis_side`) answers by one f32 comparison where
    /// the origin is off it in that coordinate: the same answer (`axis_of`'s proof).
    #[inline]
    pub fn side(&self, origin: Vec3) -> Option<f32> {
        match self.axis_side(origin) {
            Some(side) => side,
            None => self.side_f64(origin),
        }
    }

    /// [`side`](Self::side) by one f32 comparison, for a plane of constant coordinate
    /// `k` (`axis_of`): `Some(sign(n_k))` where `origin_k > v0_k`, its negation where
    /// below; level with it (`origin_k == v0_k`: a floor point whose error bound is
    /// zero across the floor keeps its origin on it), `side_f64`'s answer there:
    /// `Some(0.0)` where `n` and the f64 differences of the two other coordinates are
    /// exact, else none (`s = ±0` with an exactness flag down, a margin of zero);
    /// `None` (no answer here) where the plane is not such a plane or `origin_k` is NaN.
    ///
    /// Measured (dof_area 640x480, 1 thread, AVX-512, perf): `side` in f64 was 5.3 % of
    /// the frame, one call per shading point (the floor's plane for each pack point's
    /// origin, `LaneOccluders::settle_segments`); with the comparison alone (no level
    /// case) still 4.3 %: most floor points' origins are level with the floor.
    #[inline(always)]
    pub fn axis_side(&self, origin: Vec3) -> Option<Option<f32>> {
        let (k, sign) = self.axis?;
        let (o, c) = (origin[k], self.v0[k]);
        if o > c {
            Some(Some(sign))
        } else if o < c {
            Some(Some(-sign))
        } else if o == c {
            let exact = |j: usize| sub_exact(origin[j] as f64, self.v0[j] as f64).1;
            let (j, l) = ((k + 1) % 3, (k + 2) % 3);
            Some((self.n_exact && exact(j) && exact(l)).then_some(0.0))
        } else {
            None
        }
    }

    /// [`side`](Self::side) in f64 (the exact test and its error bound), for every
    /// plane and origin.
    pub fn side_f64(&self, origin: Vec3) -> Option<f32> {
        let mut exact = self.n_exact;
        let (mut s, mut bound) = (0.0f64, 0.0f64);
        for k in 0..3 {
            let (w, x) = sub_exact(origin[k] as f64, self.v0[k] as f64);
            let (p, y) = mul_exact(self.n[k], w);
            let (sum, z) = add_exact(s, p);
            exact &= x && y && z;
            s = sum;
            bound += self.terms[k] * w.abs();
        }
        let margin = 1e-12 * bound;
        if exact {
            Some(if s > 0.0 {
                1.0
            } else if s < 0.0 {
                -1.0
            } else {
                0.0
            })
        } else if s > margin {
            Some(1.0)
        } else if s < -margin {
            Some(-1.0)
        } else {
            None
        }
    }

    /// The lanes of `live` whose direction `d` certainly leaves the plane away from an
    /// origin on `side` (from [`side`](Self::side)): `n · d` of the sign of `side`, or
    /// of either sign for an origin on the plane, clear of the margin.
    #[inline(always)]
    pub fn leaving(&self, side: f32, d: &[TinyLanes; 3], live: u32) -> u32 {
        let (up, down) = self.away(d, live);
        if side > 0.0 {
            up
        } else if side < 0.0 {
            down
        } else {
            up | down
        }
    }

    /// `(up, down)`: the lanes of `live` whose direction `d` leaves the plane along `n`
    /// and against it, clear of the margin; [`leaving`](Self::leaving) is `up` from the
    /// side `n` points to, `down` from the other, both from the plane. For lanes whose
    /// origins lie on different sides (a pack of shading points).
    #[inline(always)]
    pub fn away(&self, d: &[TinyLanes; 3], live: u32) -> (u32, u32) {
        let [nx, ny, nz] = self.n32.map(TinyLanes::splat);
        let [tx, ty, tz] = self.terms32.map(|t| TinyLanes::splat(1e-5 * t));
        let nd = nx * d[0] + ny * d[1] + nz * d[2];
        let margin = tx * d[0].abs() + ty * d[1].abs() + tz * d[2].abs();
        let up = nd.simd_gt(margin).to_bitmask();
        let down = nd.simd_lt(TinyLanes::splat(0.0) - margin).to_bitmask();
        (up & live, down & live)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{spawn_ray_to, triangle_point};
    use crate::simd::kernels::sphere_roots;
    use crate::simd::lanes3::V3;
    use crate::test_rng::xorshift64;

    /// The closest hit of `ray` by the scalar tests in the lane loop's order
    /// (triangles, then spheres, strict `t < tmax`): `(t, u, v, prim)`.
    fn scalar_closest(
        ray: &Ray,
        triangles: &[[Vec3; 3]],
        spheres: &[(Vec3, f32)],
    ) -> Option<(f32, f32, f32, u32)> {
        let q = RayQuery::new(ray).expect("a valid ray");
        let mut best = None;
        let mut tmax = ray.tmax;
        for (k, c) in triangles.iter().enumerate() {
            if let Some(h) = intersect_triangle(&q, c[0], c[1], c[2], tmax) {
                tmax = h.t;
                best = Some((h.t, h.u, h.v, k as u32));
            }
        }
        for (k, &(center, radius)) in spheres.iter().enumerate() {
            if let Some(t) = crate::geometry::intersect_sphere(&q, center, radius, tmax) {
                tmax = t;
                best = Some((t, 0.0, 0.0, (triangles.len() + k) as u32));
            }
        }
        best
    }

    /// The floor quad `y = 0`, `|x|, |z| <= h`, as two triangles sharing a diagonal.
    fn floor_quad(h: f32) -> [[Vec3; 3]; 2] {
        let [a, b, c, d] = [(-h, -h), (-h, h), (h, h), (h, -h)].map(|(x, z)| Vec3::new(x, 0.0, z));
        [[a, b, c], [a, c, d]]
    }

    /// [`TinyGroup::closest`] returns, for every lane of its mask, the scalar loop's
    /// answer bit for bit (t, u, v, primitive; no hit where the loop finds none), and
    /// for every other lane no hit, `t` the interval end, `u = v = 0` and no primitive:
    /// groups of random rays of one shear
    /// key (every key), of rays from one shared origin, and of rays
    /// aimed exactly at the triangles' corners and shared edges (edge functions of zero:
    /// the scalar fallback), against a floor quad, a coincident copy of one of its
    /// triangles (exact ties in `t`), a tilted triangle and nested spheres, with lane
    /// masks of every shape (one half empty, gaps, single lanes, all sixteen).
    #[test]
    fn closest_is_the_scalar_loop_for_every_lane_mask() {
        let floor = floor_quad(4.0);
        let triangles = [
            floor[0],
            floor[1],
            floor[1],
            [
                Vec3::new(-1.3, 0.2, -2.0),
                Vec3::new(2.1, 1.7, 0.3),
                Vec3::new(0.4, -0.8, 2.9),
            ],
        ];
        let spheres = [
            (Vec3::new(1.1, 1.3, -1.4), 1.3),
            (Vec3::new(1.1, 1.3, -1.4), 0.5),
            (Vec3::new(-0.9, 1.0, 1.0), 1.0),
        ];
        let corners = [
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(4.0, 0.0, 4.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(-4.0, 0.0, 1.5),
            Vec3::new(2.1, 1.7, 0.3),
        ];
        let mut next = xorshift64(0x0123_4567_89ab_cdef);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes_hit, mut tri_hits, mut sphere_hits, mut groups) = (0, 0, 0, [0usize; 6]);
        let (mut shared_groups, mut one_half) = (0, 0);
        for case in 0..4000 {
            let shared = case % 3 == 0;
            let r3 = |unit: &mut dyn FnMut() -> f32, s: f32| {
                Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
            };
            let common = r3(&mut unit, 8.0) + Vec3::Y * 2.0;
            let mut rays = Vec::new();
            for i in 0..64 {
                let o = if shared {
                    common
                } else {
                    r3(&mut unit, 8.0) + Vec3::Y * 2.0
                };
                let dir = if case % 5 == 0 && i % 2 == 0 {
                    corners[(i / 2) % corners.len()] - o
                } else {
                    r3(&mut unit, 2.0)
                };
                let mut r = Ray::new(o, dir);
                if i % 4 == 1 {
                    r.tmax = unit() * 6.0;
                } else if i % 4 == 2 {
                    r.tmin = unit() * 2.0;
                }
                rays.push(r);
            }
            for (key, count) in groups.iter_mut().enumerate() {
                let of_key: Vec<&Ray> = rays.iter().filter(|r| shear_key(r) == Some(key)).collect();
                if of_key.is_empty() {
                    continue;
                }
                let lane_ray: Vec<&Ray> =
                    (0..TINY_WIDTH).map(|i| of_key[i % of_key.len()]).collect();
                let (lanes, tmax) = RayLanes::gather(lane_ray.iter().copied());
                let mask = match case % 6 {
                    0 => 0xffff,
                    1 => 0x00ff,
                    2 => 0xff00,
                    3 => 1 << (case / 6 % 16),
                    _ => (unit() * 65536.0) as u32 & 0xffff | 1,
                };
                let g = TinyGroup::from_lanes(key, lanes, tmax, mask);
                let a = g.closest(&triangles, &spheres);
                assert_eq!(a.hit & !mask, 0, "case {case} key {key}");
                let tm = tmax.to_array();
                for i in (0..TINY_WIDTH).filter(|i| mask >> i & 1 == 0) {
                    let got = (a.t[i].to_bits(), a.u[i], a.v[i], a.prim[i]);
                    assert_eq!(got, (tm[i].to_bits(), 0.0, 0.0, u32::MAX), "case {case}");
                }
                for (i, r) in lane_ray
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| mask >> i & 1 == 1)
                {
                    let want = scalar_closest(r, &triangles, &spheres);
                    let got = (a.hit >> i & 1 == 1).then(|| (a.t[i], a.u[i], a.v[i], a.prim[i]));
                    let bits = |h: Option<(f32, f32, f32, u32)>| {
                        h.map(|(t, u, v, p)| (t.to_bits(), u.to_bits(), v.to_bits(), p))
                    };
                    assert_eq!(
                        bits(got),
                        bits(want),
                        "case {case} key {key} lane {i} {r:?}"
                    );
                    if let Some((_, _, _, p)) = want {
                        lanes_hit += 1;
                        if p < triangles.len() as u32 {
                            tri_hits += 1;
                        } else {
                            sphere_hits += 1;
                        }
                    }
                }
                *count += 1;
                shared_groups += shared as usize;
                one_half += (mask & 0xff == 0 || mask >> 8 == 0) as usize;
            }
        }
        eprintln!(
            "{groups:?} groups per key, {shared_groups} shared-origin, {one_half} with one \
             half empty; {lanes_hit} hit lanes, {tri_hits} on triangles, {sphere_hits} on spheres"
        );
        assert!(groups.iter().all(|&n| n > 100), "{groups:?}");
        assert!(shared_groups > 1000 && one_half > 2000);
        assert!(tri_hits > 10_000 && sphere_hits > 10_000);
    }

    /// Sphere lane groups whose every ray passes the sphere by (where `sphere_lanes`
    /// stops after the discriminant, `kernels::roots_of`) and groups with a few lanes
    /// grazing it: [`TinyGroup::closest`] and [`TinyGroup::any_sphere`] give every lane
    /// the scalar test's answer ([`intersect_sphere`](crate::geometry::intersect_sphere):
    /// same `t` bits, same sphere, same occlusion). Rays pass the sphere's centre at
    /// `1 +- 1e-7 .. 1e-5` of its radius (discriminants of both signs near zero) or at
    /// 1.5 and 4 radii, in groups of every lane or every other lane; both kinds of group
    /// occur.
    #[test]
    fn sphere_groups_passing_by_together_get_the_scalar_answers() {
        let mut next = xorshift64(0x2545_f491_4f6c_dd1d);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let scales = [
            1.0 - 1e-5f32,
            1.0 - 1e-7,
            1.0,
            1.0 + 1e-7,
            1.0 + 1e-5,
            1.5,
            4.0,
        ];
        let (mut none_real, mut some_hit, mut lanes) = (0usize, 0usize, 0usize);
        for case in 0..3000 {
            let r3 = |unit: &mut dyn FnMut() -> f32, s: f32| {
                Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
            };
            let center = r3(&mut unit, 10.0);
            let radius = 0.1 + unit() * 3.0;
            let spheres = [(center, radius), (center + r3(&mut unit, 20.0), radius)];
            let eye = center + r3(&mut unit, 2.0).normalize_or(Vec3::Z) * radius * 6.0;
            // Most groups pass both spheres by; one in four has a few lanes grazing one.
            let grazing = case % 4 == 0;
            let rays: Vec<Ray> = (0..64)
                .map(|i| {
                    let o = eye + r3(&mut unit, radius * 0.5);
                    let to = center - o;
                    let side = to.cross(r3(&mut unit, 2.0)).normalize_or(Vec3::X);
                    let scale = if grazing && i % 5 == 0 {
                        scales[i % 5]
                    } else {
                        scales[5 + i % 2]
                    };
                    // The offset in the plane through the centre at which the line
                    // passes the centre at `radius * scale`.
                    let (dist, pass) = (to.length(), radius * scale);
                    Ray::new(
                        o,
                        to + side * (pass * dist / (dist * dist - pass * pass).sqrt()),
                    )
                })
                .collect();
            for key in 0..6 {
                let ids: Vec<u32> = (0..rays.len() as u32)
                    .filter(|&i| shear_key(&rays[i as usize]) == Some(key))
                    .collect();
                for chunk in ids.chunks(TINY_WIDTH) {
                    let full = TinyGroup::new(&rays, chunk, key);
                    // Every lane, or every other one.
                    let mask = if case % 3 == 1 {
                        full.mask & 0x5555
                    } else {
                        full.mask
                    };
                    if mask == 0 {
                        continue;
                    }
                    let g = TinyGroup { mask, ..full };
                    let (_, _, roots) = sphere_roots(&g.lanes, center, radius);
                    none_real += (roots & mask == 0) as usize;
                    let a = g.closest(&[], &spheres);
                    let blocked = g.any_sphere(&spheres, mask);
                    some_hit += (a.hit != 0) as usize;
                    for (i, &id) in chunk.iter().enumerate() {
                        if mask >> i & 1 == 0 {
                            assert_eq!(a.hit >> i & 1, 0);
                            continue;
                        }
                        let r = &rays[id as usize];
                        let want = scalar_closest(r, &[], &spheres);
                        let got = (a.hit >> i & 1 == 1).then(|| (a.t[i].to_bits(), a.prim[i]));
                        assert_eq!(got, want.map(|(t, _, _, p)| (t.to_bits(), p)), "{r:?}");
                        assert_eq!(blocked >> i & 1 == 1, want.is_some(), "{r:?}");
                        lanes += 1;
                    }
                }
            }
        }
        eprintln!("{lanes} lanes: {none_real} groups with no root, {some_hit} with a hit");
        assert!(
            none_real > 3000 && some_hit > 300,
            "{none_real} / {some_hit}"
        );
    }

    /// The axis-plane cull of [`TinyGroup::closest`] on the rays of a Whitted frame:
    /// camera rays of the whitted camera (those above the horizon leave the floor's
    /// plane from above and skip both floor triangles), and each floor hit's mirror
    /// reflection from its offset origin (`offset_ray_origin`, as the shader spawns
    /// it; most of them leave the plane), taken sixteen at a time per shear key into
    /// lanes: every lane gets the scalar loop's answer bit for bit (t, u, v, primitive),
    /// and both kinds of rays skip the floor in some groups.
    #[test]
    fn closest_skips_the_floor_only_where_the_scalar_loop_misses_it() {
        use crate::geometry::offset_ray_origin;
        use crate::scene::Camera;
        let floor = floor_quad(1000.0);
        let spheres = [
            (Vec3::new(1.1, 1.3, -1.4), 1.3),
            (Vec3::new(-0.9, 1.0, 1.0), 1.0),
        ];
        let camera = Camera {
            eye: Vec3::new(0.0, 1.8, 7.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            vfov_deg: 40.1,
        };
        let (w, h) = (160, 120);
        let frame = camera.frame(w, h);
        let camera_rays: Vec<Ray> = (0..w * h)
            .map(|i| frame.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5))
            .collect();
        let mut reflected = Vec::new();
        for r in &camera_rays {
            if let Some((t, _, _, p)) = scalar_closest(r, &floor, &spheres)
                && p < 2
            {
                let p = r.at(t);
                // The hit point's error bound as the triangle hit computes it, roughly:
                // the offset only has to be the renderer's kind, not its exact value.
                let err = Vec3::splat(p.abs().max_element() * 4.0 * f32::EPSILON);
                let d = r.dir.normalize();
                let dir = d - 2.0 * d.dot(Vec3::Y) * Vec3::Y;
                reflected.push(Ray::new(offset_ray_origin(p, err, Vec3::Y, dir), dir));
            }
        }
        assert!(reflected.len() > 5000, "{} floor hits", reflected.len());
        let (mut lanes, mut skipped) = ([0usize; 2], [0usize; 2]);
        for (kind, rays) in [camera_rays, reflected].iter().enumerate() {
            for key in 0..6 {
                let of_key: Vec<&Ray> = rays.iter().filter(|r| shear_key(r) == Some(key)).collect();
                for chunk in of_key.chunks(TINY_WIDTH) {
                    let (l, tmax) = RayLanes::gather(chunk.iter().copied());
                    let mask = ((1u64 << chunk.len()) - 1) as u32;
                    let g = TinyGroup::from_lanes(key, l, tmax, mask);
                    let o = V3 {
                        x: l.o[0],
                        y: l.o[1],
                        z: l.o[2],
                    };
                    let d = V3 {
                        x: l.d[0],
                        y: l.d[1],
                        z: l.d[2],
                    };
                    let plane = AxisPlane::of(&floor[0]).expect("the floor is axis-aligned");
                    skipped[kind] += plane.leaving(&o, &d, mask).count_ones() as usize;
                    let a = g.closest(&floor, &spheres);
                    for (i, r) in chunk.iter().enumerate() {
                        let want = scalar_closest(r, &floor, &spheres);
                        let got =
                            (a.hit >> i & 1 == 1).then(|| (a.t[i], a.u[i], a.v[i], a.prim[i]));
                        let bits = |h: Option<(f32, f32, f32, u32)>| {
                            h.map(|(t, u, v, p)| (t.to_bits(), u.to_bits(), v.to_bits(), p))
                        };
                        assert_eq!(bits(got), bits(want), "kind {kind} key {key} {r:?}");
                        lanes[kind] += 1;
                    }
                }
            }
        }
        eprintln!("lanes {lanes:?}, of which leaving the floor {skipped:?}");
        // Not every reflected ray: a hit point rounded below the plane by more than
        // this test's rough error bound keeps its origin there.
        assert!(
            skipped[0] > 1000 && skipped[1] > 5000,
            "{skipped:?} of {lanes:?}"
        );
    }

    /// [`TrianglePlane::axis_side`] gives `side_f64`'s answer wherever it answers, bit
    /// for bit, and `side` is `side_f64` everywhere: planes of constant x, y and z
    /// (both orientations, tiny, unit and huge extents, corners off the origin) and a
    /// tilted one (no axis), origins near the plane (a few ulps off, level), far off,
    /// huge and tiny coordinates.
    #[test]
    fn axis_sides_are_the_f64_sides() {
        let mut next = xorshift64(0x510e_527f_ade6_82d1);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut fast, mut level, mut checked) = (0usize, 0usize, 0usize);
        for case in 0..600 {
            let k = case % 3;
            let scale = [1e-30f32, 1e-3, 1.0, 6.0, 1e4, 1e30][case / 3 % 6];
            let at = (unit() - 0.5) * scale * 4.0;
            let corner = |a: f32, b: f32| {
                let mut c = [0.0f32; 3];
                c[k] = at;
                c[(k + 1) % 3] = a * scale;
                c[(k + 2) % 3] = b * scale;
                Vec3::from_array(c)
            };
            let mut c = [corner(-1.0, -1.0), corner(-1.0, 1.0), corner(1.0, -1.0)];
            if case % 2 == 1 {
                c.swap(1, 2);
            }
            let tilted = case % 7 == 6;
            if tilted {
                c[2][k] += scale * 0.5;
            }
            let plane = TrianglePlane::new(&c);
            assert_eq!(
                plane.axis.is_none(),
                tilted,
                "case {case}: {:?}",
                plane.axis
            );
            for i in 0..400 {
                let mut o = Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * scale * 8.0;
                o[k] = match i % 5 {
                    0 => at,
                    1 => f32::from_bits(at.to_bits().wrapping_add(i % 7) ^ (i & 8)),
                    2 => at + (unit() - 0.5) * scale * 1e-6,
                    3 => (unit() - 0.5) * [1e-38, 1e38][i as usize / 5 % 2],
                    _ => o[k],
                };
                if i % 10 == 5 {
                    // Level, with another coordinate far below the plane's corners
                    // (an inexact difference: no answer).
                    o[(k + 1) % 3] = unit() * 1e-30;
                }
                let want = plane.side_f64(o);
                let got = plane.axis_side(o);
                assert_eq!(got.is_none(), tilted, "case {case} {o:?}");
                if let Some(g) = got {
                    assert_eq!(
                        g.map(f32::to_bits),
                        want.map(f32::to_bits),
                        "case {case} {o:?}"
                    );
                    fast += 1;
                    level += (o[k] == plane.v0[k]) as usize;
                }
                assert_eq!(plane.side(o).map(f32::to_bits), want.map(f32::to_bits));
                checked += 1;
            }
        }
        eprintln!("{checked} origins, {fast} by the comparison, {level} level with a plane");
        assert!(fast > checked / 2 && level > checked / 10, "{fast} {level}");
    }

    /// Every lane that [`TrianglePlane`] lets skip a triangle is one the scalar test
    /// ([`intersect_triangle`], the packet test's oracle and fallback) reports no hit
    /// for: shadow segments from points on the triangle (offset as the renderer offsets
    /// them, exactly on the plane for an axis-aligned floor at y = 0) and from points
    /// off it, towards random targets on both sides, on an axis-aligned floor, a
    /// tilted and a huge triangle.
    #[test]
    fn plane_culled_lanes_are_misses_of_the_scalar_test() {
        let mut next = xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let triangles = [
            [
                Vec3::new(-4.0, 0.0, -4.0),
                Vec3::new(-4.0, 0.0, 4.0),
                Vec3::new(4.0, 0.0, -4.0),
            ],
            [
                Vec3::new(-1.3, 0.2, -2.0),
                Vec3::new(2.1, 1.7, 0.3),
                Vec3::new(0.4, -0.8, 2.9),
            ],
            [
                Vec3::new(-1000.0, 0.0, -1000.0),
                Vec3::new(-1000.0, 0.0, 1000.0),
                Vec3::new(1000.0, 0.0, -1000.0),
            ],
        ];
        let (mut culled, mut exact_on_plane, mut lanes) = (0, 0, 0);
        for c in &triangles {
            let plane = TrianglePlane::new(c);
            let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize();
            for i in 0..4000 {
                let (u, v) = (unit(), unit());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let (p, p_err) = triangle_point(*c, u, v);
                let off = (unit() - 0.5) * 4.0;
                let target = p + n * off * 3.0 + Vec3::new(unit() - 0.5, 0.0, unit() - 0.5) * 6.0;
                // Half from the surface (offset origin), half from points off it.
                let ray = if i % 2 == 0 {
                    spawn_ray_to(p, p_err, n, target, Vec3::ZERO, -n)
                } else {
                    let o = p + n * (unit() - 0.5) * 0.1;
                    crate::geometry::Ray::segment(o, target - o, 0.0, 1.0)
                };
                let Some(side) = plane.side(ray.origin) else {
                    continue;
                };
                exact_on_plane += (side == 0.0) as usize;
                let d = [ray.dir.x, ray.dir.y, ray.dir.z].map(TinyLanes::splat);
                lanes += 1;
                if plane.leaving(side, &d, 1) == 1 {
                    culled += 1;
                    let q = RayQuery::new(&ray).expect("a valid segment");
                    assert!(
                        intersect_triangle(&q, c[0], c[1], c[2], ray.tmax).is_none(),
                        "{ray:?} skipped {c:?} but hits it"
                    );
                }
            }
        }
        eprintln!("{culled} of {lanes} lanes skipped, {exact_on_plane} origins exactly on a plane");
        assert!(culled > 3_000 && exact_on_plane > 1_000);
    }

    /// Shadow segments from the shading point `[p, p_error, n]` to random points of the
    /// quad light `[corner, e1, e2]`, built as the renderer builds them (`spawn_ray_to`)
    /// with their ends moved by the case's stretch, against the light's two triangles:
    /// every lane [`TinyGroup::beyond`] skips is a miss of both the packet test
    /// (`triangle_blocks`) and the scalar test ([`intersect_triangle`]). Returns the
    /// lanes tested, the packet test's hits and the lanes skipped.
    fn beyond_case(
        case: usize,
        mut unit: impl FnMut() -> f32,
        [p, p_error, n]: [Vec3; 3],
        [corner, e1, e2]: [Vec3; 3],
        normal: Vec3,
    ) -> [usize; 3] {
        let q_error = crate::geometry::gamma(32) * (corner.abs() + e1.abs() + e2.abs());
        let tris = [
            [corner, corner + e1, corner + e1 + e2],
            [corner, corner + e1 + e2, corner + e2],
        ];
        let (mut culled, mut lanes, mut hits) = (0usize, 0usize, 0usize);
        let stretch = [0.0f32, -4.0, 1.0, 4.0, 16.0, 64.0, 256.0][case % 7] * f32::EPSILON;
        let rays: Vec<Ray> = (0..TINY_WIDTH)
            .map(|_| {
                let point = corner + e1 * unit() + e2 * unit();
                let mut r = spawn_ray_to(p, p_error, n, point, q_error, normal);
                r.tmax *= 1.0 + stretch;
                r
            })
            .collect();
        for key in 0..6 {
            let ids: Vec<u32> = (0..rays.len() as u32)
                .filter(|&i| shear_key(&rays[i as usize]) == Some(key))
                .collect();
            if ids.is_empty() {
                continue;
            }
            let g = TinyGroup::new(&rays, &ids, key);
            for c in &tris {
                let skip = g.beyond(c, g.mask);
                let blocked = g.triangle_blocks(c, g.mask);
                lanes += ids.len();
                hits += blocked.count_ones() as usize;
                culled += skip.count_ones() as usize;
                assert_eq!(skip & blocked, 0, "case {case}: the packet test hits");
                for (i, &id) in ids.iter().enumerate() {
                    let ray = &rays[id as usize];
                    let q = RayQuery::new(ray).expect("a valid segment");
                    let hit = intersect_triangle(&q, c[0], c[1], c[2], ray.tmax);
                    assert!(
                        skip >> i & 1 == 0 || hit.is_none(),
                        "case {case}: {ray:?} skipped {c:?} but the scalar test hits it"
                    );
                }
            }
        }
        [lanes, hits, culled]
    }

    /// Every lane that [`TinyGroup::beyond`] lets skip a triangle is one both the
    /// packet test (`triangle_blocks`) and the scalar test ([`intersect_triangle`])
    /// report no hit for: shadow segments built as the renderer builds them
    /// (`spawn_ray_to`) from random points towards random points of random quad lights
    /// (axis-aligned like the Whitted rows' light, and tilted), tested against the
    /// light's own two triangles, with the segments' ends also pushed towards and past
    /// the light by a few ulps to a few hundred (where the margin is what decides).
    #[test]
    fn beyond_culled_lanes_are_misses_of_both_tests() {
        let mut next = xorshift64(0x51_7cc1_b727_220a);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut culled, mut lanes, mut hits) = (0usize, 0usize, 0usize);
        for case in 0..600 {
            let mut r3 = |s: f32| Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s;
            let (corner, e1, e2) = if case % 2 == 0 {
                (
                    Vec3::new(-6.0, 9.0, 6.0) + r3(2.0),
                    Vec3::X * 2.0,
                    Vec3::Z * 2.0,
                )
            } else {
                (r3(8.0) + Vec3::Y * 6.0, r3(4.0), r3(4.0))
            };
            let normal = e1.cross(e2).normalize();
            let p = r3(16.0);
            let p_error = Vec3::splat(1e-6) * (1.0 + p.abs().max_element());
            let n = r3(2.0).normalize_or(Vec3::Y);
            let [l, h, c] = beyond_case(case, &mut unit, [p, p_error, n], [corner, e1, e2], normal);
            (lanes, hits, culled) = (lanes + l, hits + h, culled + c);
        }
        eprintln!("{culled} of {lanes} lanes skipped, {hits} hits");
        assert!(
            culled > lanes / 5 && hits > 100,
            "{culled} skipped, {hits} hits"
        );
    }

    /// [`TinyGroup::beyond`] against the packet and the scalar triangle tests at every
    /// scale: the cases of `beyond_culled_lanes_are_misses_of_both_tests` in scenes of
    /// scale 1e-3, 1 and 1e4, shifted to 1e5 of the scale from the origin or not, with
    /// tiny lights (1e-4 of the scale), thin ones (one edge 1e-6 of the other), points
    /// grazing the light's plane (within 1e-5 of the scale of it, seen almost edge-on)
    /// and segment ends pushed by a few ulps to a few hundred either way.
    #[test]
    fn beyond_holds_at_every_scale() {
        fn r3(unit: &mut impl FnMut() -> f32, s: f32) -> Vec3 {
            Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
        }
        let mut next = xorshift64(0x1f83_d9ab_fb41_bd6b);
        let (mut culled, mut lanes, mut hits) = (0usize, 0usize, 0usize);
        for case in 0..3000 {
            let mut unit = || (next() >> 40) as f32 / (1u64 << 24) as f32;
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let shift = if case / 3 % 2 == 0 {
                Vec3::ZERO
            } else {
                Vec3::new(1e5, -3e4, 7e4) * scale
            };
            let size = [2.0f32, 1e-4, 2.0][case / 6 % 3] * scale;
            let (corner, e1, e2) = if case % 2 == 0 {
                (
                    shift + (Vec3::new(-6.0, 9.0, 6.0) + r3(&mut unit, 2.0)) * scale,
                    Vec3::X * size,
                    Vec3::Z * size,
                )
            } else {
                (
                    shift + (r3(&mut unit, 8.0) + Vec3::Y * 6.0) * scale,
                    r3(&mut unit, 2.0) * size,
                    r3(&mut unit, 2.0) * size,
                )
            };
            // Thin lights: one edge 1e-6 of the other.
            let e2 = if case / 18 % 4 == 3 {
                e1.cross(e2).cross(e1).normalize_or(Vec3::Z) * 1e-6 * e1.length()
            } else {
                e2
            };
            let normal = e1.cross(e2).normalize();
            if !normal.is_finite() {
                continue;
            }
            let mut p = shift + r3(&mut unit, 16.0) * scale;
            if case / 5 % 4 == 0 {
                // Grazing: the point within 1e-5 of the scale of the light's plane.
                p -= normal * (normal.dot(p - corner) - (unit() - 0.5) * 2e-5 * scale);
            }
            let p_error = crate::geometry::gamma(5) * p.abs() + Vec3::splat(1e-7 * scale);
            let n = r3(&mut unit, 2.0).normalize_or(Vec3::Y);
            let [l, h, c] = beyond_case(case, &mut unit, [p, p_error, n], [corner, e1, e2], normal);
            (lanes, hits, culled) = (lanes + l, hits + h, culled + c);
        }
        eprintln!("{culled} of {lanes} lanes skipped, {hits} hits");
        assert!(
            culled > lanes / 5 && hits > 100,
            "{culled} skipped, {hits} hits"
        );
    }

    /// [`TrianglePlane::may_cull_lanes`] against [`TrianglePlane::may_cull`] lane by
    /// lane: planes of constant coordinate and tilted ones, points on them (their
    /// vertices, exactly), near and far off both sides, with NaN and infinite
    /// coordinates; `to` a quad in the plane (its own light), above it, below it,
    /// straddling it, one point and none.
    #[test]
    fn lane_may_cull_answers_as_may_cull() {
        let mut next = xorshift64(0x3c6e_f372_fe94_f82b);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes, mut yes, mut no) = (0usize, 0usize, 0usize);
        for case in 0..3000 {
            let r3 = |unit: &mut dyn FnMut() -> f32, s: f32| {
                Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
            };
            let v0 = r3(&mut unit, 8.0);
            let (e1, e2) = if case % 3 == 0 {
                (
                    Vec3::new(unit() * 3.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, unit() * 3.0),
                )
            } else {
                (r3(&mut unit, 4.0), r3(&mut unit, 4.0))
            };
            let tri = [v0, v0 + e1, v0 + e2];
            let plane = TrianglePlane::new(&tri);
            let n = e1.cross(e2).normalize_or(Vec3::Y);
            let lift = [0.0f32, 2.0, -2.0, 1e-6][case % 4];
            let quad = [v0, v0 + e1, v0 + e1 + e2, v0 + e2].map(|c| c + n * lift);
            let straddle = [v0 + n, v0 - n + e1, v0 + e2];
            let to: &[Vec3] = match case % 6 {
                0..=2 => &quad,
                3 => &straddle,
                4 => &quad[..1],
                _ => &[],
            };
            let from: [Vec3; 16] = std::array::from_fn(|i| match i {
                0 => v0,
                1 => tri[1],
                2 => v0 + e1 * unit() + e2 * unit(),
                3 => Vec3::new(f32::NAN, 0.0, 0.0),
                4 => Vec3::new(0.0, f32::INFINITY, 0.0),
                5 => v0 + n * 1e-7,
                6 => v0 - n * 1e-7,
                _ => v0 + r3(&mut unit, 6.0) + n * (unit() - 0.5) * 4.0,
            });
            let lanes_from = V3 {
                x: Packet::new(from.map(|v| v.x)),
                y: Packet::new(from.map(|v| v.y)),
                z: Packet::new(from.map(|v| v.z)),
            };
            let got = plane.may_cull_lanes(lanes_from, to);
            for (i, f) in from.iter().enumerate() {
                let want = plane.may_cull(*f, to);
                assert_eq!(
                    got >> i & 1 == 1,
                    want,
                    "case {case} lane {i}: {f} to {to:?}"
                );
                lanes += 1;
                (yes, no) = (yes + want as usize, no + !want as usize);
            }
        }
        assert!(
            lanes == 48_000 && yes > 5_000 && no > 5_000,
            "{yes} yes {no} no"
        );
    }
}
