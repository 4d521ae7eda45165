//! Packet setup: lanes loaded, validity, and the split by direction octant and
//! dominant axis into groups that share slab planes and watertight shear; the
//! per-lane child slab test.

use crate::geometry::{LaneRays, ROBUST_FAR_SCALE, RayQuery};
use crate::simd::Lanes;
use crate::simd::kernels::{PacketShear, RayLanes};

/// Packet traversal over lanes of type `L`: one group's planes and shear, and the
/// packet's lanes read in place from its [`PacketSetup`].
///
/// Why in place: a copy of the lanes here (as before) was compiled as 32-byte moves,
/// and the traversal's first 64-byte loads of the copy (`tmin` and `tmax` at the
/// group's start, the origins and reciprocals in the whole-packet bounds) could not be
/// forwarded from those stores and waited for them to reach the cache: `perf annotate`
/// of `examples/stream_profile bunny.obj bvh8-packet primary 80` (AVX-512) put 2.9 % of
/// `packet_closest`'s samples on the load of `tmax`.
pub(super) struct PacketRays<'a, L: Lanes> {
    s: &'a PacketSetup<L>,
    /// The negated reciprocals, plain (near planes) and far-scaled (far planes), for
    /// [`child_test`](Self::child_test).
    neg_inv: [L; 3],
    neg_inv_far: [L; 3],
    /// Bit `a` set: the direction is negative along axis `a`, so the rays enter a box
    /// by its upper plane (see [`near_plane`]). One word, written and read whole: as
    /// three `bool`s, written by byte stores before the call into the group's
    /// traversal, the whole-packet bounds read them back with one 4-byte load, which
    /// cannot be forwarded from the three stores (6 % of `packet_closest_group`'s
    /// samples on the instruction after it, `perf annotate`, issue 12, pk22).
    pub(super) neg: u32,
    pub(super) shear: PacketShear<L>,
}

/// The index in a node's six planes (lower x, y, z, then upper) of the plane that rays
/// with direction sign `neg` enter axis `a` by. Computed where a plane is read rather
/// than kept as an index: an index read from memory is bounds-checked at every read
/// (six compares and branches per node and per leaf group of the packet kernels).
#[inline(always)]
pub(super) fn near_plane(neg: u32, a: usize) -> usize {
    a + 3 * (neg >> a & 1) as usize
}

/// The plane rays with direction sign `neg` leave axis `a` by (see [`near_plane`]).
#[inline(always)]
pub(super) fn far_plane(neg: u32, a: usize) -> usize {
    a + 3 * (!neg >> a & 1) as usize
}

impl<L: Lanes> PacketRays<'_, L> {
    /// Origins.
    #[inline(always)]
    pub(super) fn o(&self) -> &[L; 3] {
        &self.s.o
    }
    /// Reciprocal directions.
    #[inline(always)]
    pub(super) fn inv(&self) -> &[L; 3] {
        &self.s.inv
    }
    /// Starts of the rays' intervals.
    #[inline(always)]
    pub(super) fn tmin(&self) -> L {
        self.s.tmin
    }
    /// Ends of the rays' intervals.
    #[inline(always)]
    pub(super) fn tmax(&self) -> L {
        self.s.tmax
    }

    /// The first valid lane's origin: every lane's where the packet's origin is shared
    /// (`PacketSetup::shared_origin`), for the whole-packet bounds.
    ///
    /// Read here from the lanes in place, where the bounds are built. Issue 12, pk22:
    /// before, `group` read it from the lanes for every group (shared or not) and kept
    /// it in the group's state, written as three 4-byte stores that the bounds read
    /// back (after the call into the group's traversal) with an 8-byte load spanning two
    /// of them, which cannot be forwarded and waited for the stores to reach the cache:
    /// `perf annotate` of `examples/stream_profile bunny.obj bvh8-packet primary 100`
    /// (AVX-512) put 4.4 % of `packet_closest_group`'s samples on the load after it.
    #[inline(always)]
    pub(super) fn first_origin(&self) -> [f32; 3] {
        [0, 1, 2].map(|k| self.s.o[k].to_array().as_ref()[self.s.first])
    }

    /// Origins, directions and `tmin` as lanes, for scalar-leaf primitives' lane tests
    /// (built where a scalar leaf needs them: a copy kept in every packet's traversal
    /// state cost seven vector moves per group, and its reload stalled on store forwarding).
    #[inline(always)]
    pub(super) fn lanes(&self) -> RayLanes<L> {
        RayLanes {
            o: self.s.o,
            d: self.s.d,
            tmin: self.s.tmin,
        }
    }

    /// Slab test of child `c` of a node (its `planes`) for every lane: entry distances
    /// and hit bits. `tcull` is the closest hit so far, already scaled by
    /// `ROBUST_FAR_SCALE`.
    #[inline(always)]
    pub(super) fn child_test<const N: usize>(
        &self,
        p: &[[f32; N]; 6],
        c: usize,
        tcull: L,
    ) -> (L, u32) {
        // `(o - p) * -inv`, the negation of `(p - o) * inv` bit for bit (rounding to
        // nearest is symmetric) but for the sign of a zero, which no comparison sees:
        // the plane is broadcast straight from memory into the subtraction (one
        // instruction). Before, `(p - o) * inv` with a shared origin was a scalar load,
        // scalar subtraction, broadcast and multiply per plane (the broadcast operand
        // of a subtraction can only be its second), and without one a broadcast load,
        // subtraction and multiply. Issue 12, pk19: bunny, `bench --threads 1 --reps 5
        // --modes bvh4-packet,bvh8-packet`, 6 rounds interleaved with the build before,
        // load 4.5-5, Mrays per CPU-second, min/median/max: bvh8-packet primary
        // 26.72/36.29/40.59 -> 30.71/39.33/40.15 (+8.4 %), bvh4-packet primary
        // 22.58/33.77/37.45 -> 29.37/36.85/42.69 (+9.1 %); shadow level (0.99x: without
        // a shared origin the count of arithmetic instructions is unchanged); same
        // checksums.
        let rel = |plane: usize, a: usize| self.s.o[a] - L::splat(p[plane][c]);
        let d = |plane: usize, a: usize| rel(plane, a) * self.neg_inv[a];
        let f = |plane: usize, a: usize| rel(plane, a) * self.neg_inv_far[a];
        let (near, far) = (
            |a: usize| near_plane(self.neg, a),
            |a: usize| far_plane(self.neg, a),
        );
        let enter = d(near(0), 0).maxps(d(near(1), 1).maxps(d(near(2), 2).maxps(self.s.tmin)));
        let exit = f(far(0), 0).minps(f(far(1), 1).minps(f(far(2), 2).minps(tcull)));
        // Tried, no win (issue 12, pk17): a lane that misses the box given entry NaN
        // (`select(hit, enter, NaN)`), so that the active mask at the pop counts only
        // the lanes that entered the subtree, as Embree's hybrid traversal does
        // (`tNear = select(vmask, lnearP, inf)`): here a missing lane keeps a finite
        // entry and stays "active" below. 10^6 primary, `stream_profile /tmp/m1e6.obj
        // MODE primary 7` (AVX-512, 1 thread, load ~6, Mrays/s medians, before / after,
        // interleaved): bvh8-packet 10.47 / 9.58 and 8.09 / 8.12, `@5` 9.96 / 8.55,
        // `@8` 9.13 / 6.60: honest counts send more subtrees ray by ray, and the
        // one-ray kernel is the slower way through them.
        (enter, enter.le(exit).bitmask())
    }
}

/// The query of valid lane `i` of a packet (built in registers for a `RayPacket`: a
/// `Ray` written to memory field by field and read back with vector loads right away
/// stalls on store forwarding).
#[inline(always)]
pub(super) fn lane_query<R: LaneRays + ?Sized>(rays: &R, i: usize) -> RayQuery {
    rays.lane_query(i)
        .expect("packet setup passes valid lanes only")
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
pub(super) fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// A packet loaded into lanes, its valid lanes, and its lane groups of equal direction
/// octant and dominant axis (at most three; more means incoherent). Validity, reciprocal
/// and dominant axis are computed lane-parallel with the same operations as
/// `Ray::is_valid` and `RayQuery::new`, so every lane agrees with the scalar path.
pub(super) struct PacketSetup<L: Lanes> {
    pub(super) o: [L; 3],
    pub(super) d: [L; 3],
    pub(super) inv: [L; 3],
    pub(super) tmin: L,
    pub(super) tmax: L,
    pub(super) valid: u32,
    /// Every valid lane starts at the first valid lane's origin (camera rays).
    pub(super) shared_origin: bool,
    /// The first valid lane (0 if none).
    first: usize,
    pub(super) groups: usize,
    pub(super) group_mask: [u32; 3],
    /// (octant sign bits, kz) per group.
    pub(super) group_key: [(u32, usize); 3],
}

impl<L: Lanes> PacketSetup<L> {
    #[inline(always)]
    pub(super) fn new<R: LaneRays + ?Sized>(rays: &R) -> Self {
        // Lanes past the count may hold anything: they are masked off from `valid` below.
        let [ox, oy, oz, dx, dy, dz, tmin, tmax] = rays.load_lanes::<L>();
        let (o, d) = ([ox, oy, oz], [dx, dy, dz]);
        let zero = L::splat(0.0);
        let finite = o[0].is_finite()
            & o[1].is_finite()
            & o[2].is_finite()
            & d[0].is_finite()
            & d[1].is_finite()
            & d[2].is_finite();
        let nonzero = !(d[0].eq(zero) & d[1].eq(zero) & d[2].eq(zero)).bitmask();
        // tmin <= tmax is false for NaN in either, matching `Ray::is_valid`.
        let lanes = if L::WIDTH == 32 {
            u32::MAX
        } else {
            (1u32 << L::WIDTH) - 1
        };
        let valid = finite.bitmask()
            & nonzero
            & tmin.le(tmax).bitmask()
            & lanes
            & ((1u64 << rays.lane_count().min(L::WIDTH)) - 1) as u32;
        let inv = [
            L::splat(1.0) / d[0],
            L::splat(1.0) / d[1],
            L::splat(1.0) / d[2],
        ];

        // Dominant axis as in `RayQuery::new`: x if |x| >= |y| and |x| >= |z|, else y if |y| >= |z|, else z.
        let abs = |v: L| L::select(v.lt(zero), zero - v, v);
        let (ax, ay, az) = (abs(d[0]), abs(d[1]), abs(d[2]));
        let is_x = (ay.le(ax) & az.le(ax)).bitmask();
        let is_y = !is_x & az.le(ay).bitmask();
        let signs = [d[0].sign_bits(), d[1].sign_bits(), d[2].sign_bits()];

        let (shared_origin, first) = match valid {
            0 => (false, 0),
            v => {
                let i0 = v.trailing_zeros() as usize;
                let r0 = rays.lane_origin(i0);
                let same = |k: usize| o[k].eq(L::splat(r0[k])).bitmask();
                let same_bits = same(0) & same(1) & same(2);
                (valid & !same_bits == 0, i0)
            }
        };
        let mut s = PacketSetup {
            o,
            d,
            inv,
            tmin,
            tmax,
            valid,
            shared_origin,
            first,
            groups: 0,
            group_mask: [0; 3],
            group_key: [(0, 0); 3],
        };
        let mut rest = valid;
        while rest != 0 {
            let i = rest.trailing_zeros();
            let octant = (signs[0] >> i & 1) | (signs[1] >> i & 1) << 1 | (signs[2] >> i & 1) << 2;
            let kz = if is_x >> i & 1 == 1 {
                0
            } else if is_y >> i & 1 == 1 {
                1
            } else {
                2
            };
            let same_octant = !(signs[0] ^ 0u32.wrapping_sub(octant & 1))
                & !(signs[1] ^ 0u32.wrapping_sub(octant >> 1 & 1))
                & !(signs[2] ^ 0u32.wrapping_sub(octant >> 2 & 1));
            let same_axis = match kz {
                0 => is_x,
                1 => is_y,
                _ => !is_x & !is_y,
            };
            let members = rest & same_octant & same_axis;
            if s.groups == 3 {
                s.groups = 4;
                break;
            }
            s.group_mask[s.groups] = members;
            s.group_key[s.groups] = (octant, kz);
            s.groups += 1;
            rest &= !members;
        }
        s
    }

    pub(super) fn coherent(&self) -> bool {
        self.groups <= 2
    }

    /// The traversal state of group `g`: its planes and watertight shear.
    #[inline(always)]
    pub(super) fn group(&self, g: usize) -> PacketRays<'_, L> {
        let (octant, kz) = self.group_key[g];
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if octant >> kz & 1 == 1 {
            std::mem::swap(&mut kx, &mut ky);
        }
        // `1 / d[kz]`, the same division as `inv[kz]` (one fewer per group on the
        // setup's critical path).
        let sz = self.inv[kz];
        PacketRays {
            s: self,
            neg_inv: self.inv.map(|x| L::splat(-1.0) * x),
            neg_inv_far: self.inv.map(|x| x * L::splat(-ROBUST_FAR_SCALE)),
            neg: octant,
            shear: PacketShear::new(&self.d, sz, (kx, ky, kz)),
        }
    }
}
