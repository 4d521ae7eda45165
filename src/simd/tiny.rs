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

/// The [`shear_key`] shared by all [`TINY_WIDTH`] rays in `lanes` (interval ends
/// `tmax`), or `None` when a ray is invalid (`Ray::is_valid` in lanes: finite origin
/// and direction, a non-zero direction, an interval with no NaN and `tmin <= tmax`)
/// or two keys differ. `dominant_axis` in lanes: x where |x| is at least |y| and |z|,
/// else y where |y| >= |z|, else z.
#[inline(always)]
pub fn uniform_shear_key(lanes: &RayLanes<TinyLanes>, tmax: TinyLanes) -> Option<usize> {
    let [ox, oy, oz] = lanes.o;
    let [dx, dy, dz] = lanes.d;
    let finite = ox.is_finite() & oy.is_finite() & oz.is_finite();
    let finite = finite & dx.is_finite() & dy.is_finite() & dz.is_finite();
    let zero = TinyLanes::splat(0.0);
    let null = dx.simd_eq(zero) & dy.simd_eq(zero) & dz.simd_eq(zero);
    let interval = lanes.tmin.simd_le(tmax);
    let all = (1u32 << TINY_WIDTH) - 1;
    if (finite & interval).to_bitmask() != all || null.to_bitmask() != 0 {
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

/// Up to [`TINY_WIDTH`] valid rays of the same [`shear_key`], as lanes.
pub struct TinyGroup<'a> {
    pub lanes: RayLanes<TinyLanes>,
    pub tmax: TinyLanes,
    pub shear: PacketShear<TinyLanes>,
    /// Bits of the lanes holding a ray.
    pub mask: u32,
    /// The batch and the index in it of each lane's ray, for the scalar fallback of
    /// uncertain triangle edges.
    rays: &'a [Ray],
    ids: &'a [u32],
}

impl<'a> TinyGroup<'a> {
    /// The group of the rays `rays[ids[i]]` (at most [`TINY_WIDTH`], all valid, all
    /// of key `key`), gathered straight into lanes.
    #[inline]
    pub fn new(rays: &'a [Ray], ids: &'a [u32], key: usize) -> TinyGroup<'a> {
        debug_assert!(ids.len() <= TINY_WIDTH);
        let (lanes, tmax) = RayLanes::gather(ids.iter().map(|&id| {
            let r = &rays[id as usize];
            debug_assert_eq!(shear_key(r), Some(key));
            r
        }));
        Self::from_lanes(rays, ids, key, lanes, tmax)
    }

    /// The group of the rays `rays[ids[i]]` already gathered into `lanes` (interval
    /// ends `tmax`), all valid and of key `key`.
    #[inline(always)]
    pub fn from_lanes(
        rays: &'a [Ray],
        ids: &'a [u32],
        key: usize,
        lanes: RayLanes<TinyLanes>,
        tmax: TinyLanes,
    ) -> TinyGroup<'a> {
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
            shear: PacketShear {
                o,
                shared_origin: [0.0; 3],
                kx,
                ky,
                kz,
                sx: d[kx] * sz,
                sy: d[ky] * sz,
                sz,
                tmin,
            },
            mask: ((1u64 << ids.len()) - 1) as u32,
            rays,
            ids,
        }
    }

    /// The scalar query of lane `i` (a valid ray).
    fn query(&self, i: usize) -> RayQuery {
        RayQuery::new(&self.rays[self.ids[i] as usize]).expect("a tiny group holds valid rays only")
    }

    /// Closest hits over `triangles` then `spheres` (index order, strict `t < tmax`),
    /// as [`TinyHits`]: triangle `k` is prim `k`, sphere `k` is prim `triangles.len() + k`.
    pub fn closest(&self, triangles: &[[Vec3; 3]], spheres: &[(Vec3, f32)]) -> TinyHits {
        let mut tmax = self.tmax;
        let zero = TinyLanes::splat(0.0);
        let (mut tu, mut tv) = (zero, zero);
        let mut prim = [u32::MAX; TINY_WIDTH];
        let mut hit = 0u32;
        for (k, corners) in triangles.iter().enumerate() {
            let (t, u, v, mut bits, edge) =
                triangle_packet_corners::<TinyLanes, false>(&self.shear, corners, tmax, self.mask);
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
                hit |= bits;
                for_each_bit(bits, |i| prim[i] = k as u32);
            }
        }
        for (k, &(center, radius)) in spheres.iter().enumerate() {
            let (t, bits) = sphere_lanes(&self.lanes, center, radius, tmax, self.mask);
            if bits != 0 {
                let sel = TinyLanes::mask_from_bits(bits);
                tmax = TinyLanes::select(sel, t, tmax);
                tu = TinyLanes::select(sel, zero, tu);
                tv = TinyLanes::select(sel, zero, tv);
                hit |= bits;
                for_each_bit(bits, |i| prim[i] = (triangles.len() + k) as u32);
            }
        }
        TinyHits {
            t: tmax.to_array(),
            u: tu.to_array(),
            v: tv.to_array(),
            prim,
            hit,
        }
    }

    /// Occlusion by `triangles` (bits of the lanes blocked by any of them).
    pub fn any_triangle(&self, triangles: &[[Vec3; 3]]) -> u32 {
        let mut blocked = 0u32;
        let tm = self.tmax.to_array();
        for corners in triangles {
            let live = self.mask & !blocked;
            if live == 0 {
                break;
            }
            let (_, _, _, bits, edge) =
                triangle_packet_corners::<TinyLanes, false>(&self.shear, corners, self.tmax, live);
            blocked |= bits;
            for_each_bit(edge, |i| {
                let q = self.query(i);
                if intersect_triangle(&q, corners[0], corners[1], corners[2], tm[i]).is_some() {
                    blocked |= 1 << i;
                }
            });
        }
        blocked
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
