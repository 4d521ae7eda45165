//! SIMD twins of the scalar kernels in `geometry`: the same operations in the same
//! order, lane by lane, so that results agree bit for bit with the scalar oracle (Rust
//! never fuses a multiply and an add on its own, and neither do these kernels).

use super::{F4, Lanes, PACKET_WIDTH, Packet};
use crate::geometry::triangle_err as err;
use crate::geometry::{PrimHit, Ray, RayQuery, intersect_triangle};
use glam::Vec3;

/// Four triangles of a leaf, structure-of-arrays: `v[corner][axis][lane]`.
///
/// Corners rather than edges (`v0, e1, e2`) because the watertight test of Woop et al.
/// translates each corner to the ray origin before shearing; edges would have to be
/// turned back into corners per ray. Unused lanes hold NaN corners and id `u32::MAX`
/// and are masked off before any hit is reported.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct TriGroup4 {
    pub v: [[[f32; 4]; 3]; 3],
    /// Original triangle index per lane; `u32::MAX` for an unused lane.
    pub ids: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<TriGroup4>() == 160);

impl TriGroup4 {
    pub const EMPTY: TriGroup4 = TriGroup4 {
        v: [[[f32::NAN; 4]; 3]; 3],
        ids: [u32::MAX; 4],
    };

    pub fn set(&mut self, lane: usize, id: u32, corners: [Vec3; 3]) {
        for (c, p) in corners.iter().enumerate() {
            for axis in 0..3 {
                self.v[c][axis][lane] = p[axis];
            }
        }
        self.ids[lane] = id;
    }

    pub fn corners(&self, lane: usize) -> [Vec3; 3] {
        let c = |k: usize| Vec3::new(self.v[k][0][lane], self.v[k][1][lane], self.v[k][2][lane]);
        [c(0), c(1), c(2)]
    }

    /// Bits of the lanes that hold a triangle: one lane compare of the ids with
    /// `u32::MAX` and its sign mask (the lane-by-lane filter it replaced was 14 scalar
    /// instructions per leaf group in callgrind of the AVX2 build).
    #[inline(always)]
    pub fn valid_bits(&self) -> u32 {
        let ids: wide::i32x4 = wide::bytemuck::cast(self.ids);
        let unused: F4 = wide::bytemuck::cast(ids.simd_eq(wide::i32x4::splat(-1)));
        !unused.bitmask() & 0xF
    }
}

/// One ray against the four triangles of a group: the lane of the closest hit in
/// `(q.tmin, tmax)` and the hit. Ties go to the lowest lane, as in a sequential loop.
#[inline(always)]
pub fn triangle4_closest(q: &RayQuery, g: &TriGroup4, tmax: f32) -> Option<(usize, PrimHit)> {
    let (t, u, v, bits) = triangle4(q, g, tmax);
    if bits == 0 {
        return None;
    }
    let mut best = bits.trailing_zeros() as usize;
    let mut rest = bits & (bits - 1);
    while rest != 0 {
        let i = rest.trailing_zeros() as usize;
        if t[i] < t[best] {
            best = i;
        }
        rest &= rest - 1;
    }
    Some((
        best,
        PrimHit {
            t: t[best],
            u: u[best],
            v: v[best],
        },
    ))
}

/// One ray against a group: does any triangle lie in `(q.tmin, tmax)`?
#[inline(always)]
pub fn triangle4_any(q: &RayQuery, g: &TriGroup4, tmax: f32) -> bool {
    triangle4(q, g, tmax).3 != 0
}

/// Lane twin of `geometry::triangle`'s `edge_error_bound` (same operations, same
/// order; `maxps` equals `f32::max` on the non-NaN values of valid lanes).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn edge_error_bound<L: Lanes>(
    ax: L,
    ay: L,
    bx: L,
    by: L,
    cx: L,
    cy: L,
    a_z: L,
    b_z: L,
    c_z: L,
) -> L {
    let max_x = ax.abs().maxps(bx.abs()).maxps(cx.abs());
    let max_y = ay.abs().maxps(by.abs()).maxps(cy.abs());
    let max_z = a_z.abs().maxps(b_z.abs()).maxps(c_z.abs());
    let two_z = max_z + max_z;
    let delta_x = L::splat(err::SHEAR) * (max_x + two_z);
    let delta_y = L::splat(err::SHEAR) * (max_y + two_z);
    L::splat(2.0) * (L::splat(err::EDGE) * max_x * max_y + delta_y * max_x + delta_x * max_y)
}

/// The smallest edge bound [`certain_misses`] trusts (`2^-100`).
const CERTAIN_MISS_MIN_BOUND: f32 = 1.0 / (1u128 << 100) as f32;

/// Lanes whose edge functions prove a miss of the scalar test whatever its f64
/// fallback finds: one edge function below `-2 δE`, another above `+2 δE`, both finite,
/// and `δE >= 2^-100`. Such a lane is outside its triangle whatever the sign of its
/// third, uncertain edge function, so the lane tests (`triangle_packet_by`,
/// `triangle4`) answer its miss themselves instead of handing it to the scalar test.
///
/// Why (issue 12, pk24): `edge` used to hold every lane with some `|e| <= δE`. Rays of
/// the 10^6 procedural sphere's camera often pass near the lines through its long
/// edges, far from the edges themselves; counted with a temporary counter in
/// `examples/stream_profile 1000000 bvh8-packet primary 3`, 217,050 lanes were
/// flagged over the run and 178,115 of them (82 %) are certain misses (shadow:
/// 46,702 / 38,387; bunny primary: 22,275 / 11,700; the single-ray `triangle4`:
/// 5,080 / 2,895). Each flagged lane cost a scalar watertight test with its f64 edges
/// (`intersect_triangle` + `edges_f64`: 5 % of the 10^6 primary samples, `perf record`).
///
/// Exact (the same answer as `geometry::intersect_triangle`, the oracle of both lane
/// tests). The lane's f32 `u, v, w` and `δE` are the scalar test's (the packet test's
/// are their negations, but for zero signs, and the condition is symmetric in sign).
/// The scalar test rests on two bounds, against the edge functions `E` of the exactly
/// translated and sheared corners: (1) `|e - E| <= δE*` for the f32 value `e`, `δE*`
/// the bound's exact value (it is what lets the test trust the sign of `e` where `|e| >
/// δE`); (2) the f64 edge before its rounding to f32 is within `2^-27 δE*` of `E` (see
/// `F64_BOUND_RATIO` there). With `δE >= 2^-100` no term of the computed bound
/// underflowed past a `2^-40` part of it, so with its few roundings `δE* <= (1 + 2^-20)
/// δE`. A finite `e` had no overflow on its way (an infinite or NaN intermediate gives
/// an infinite or NaN `e`). Then `e < -2 δE` gives `E < -2 δE + (1 + 2^-20) δE < -δE / 2`
/// by (1), the f64 edge `< E + 2^-27 (1 + 2^-20) δE < -δE / 4 <= -2^-102` by (2), and
/// its rounding to f32 (monotone, `-2^-102` is an f32) is negative: strictly, so not
/// a zero. Likewise `e > 2 δE` gives a positive f64 edge. The scalar test, which takes
/// its f64 branch for this lane (some `|e| <= δE`), so sees a negative and a positive
/// edge function and returns `None` before anything else; the lane test sees `e < 0`
/// and `e' > 0` among its f32 edges (`neg & pos`), so the lane is not `inside` and its
/// hit bit is clear. NaN `δE` or edges fail the comparisons and stay in `edge`.
#[inline(always)]
fn certain_misses<L: Lanes>(u: L, v: L, w: L, delta_e: L) -> u32 {
    let lim = delta_e + delta_e;
    let neg_lim = L::splat(0.0) - lim;
    let below = (u.lt(neg_lim) & u.is_finite())
        | (v.lt(neg_lim) & v.is_finite())
        | (w.lt(neg_lim) & w.is_finite());
    let above =
        (u.gt(lim) & u.is_finite()) | (v.gt(lim) & v.is_finite()) | (w.gt(lim) & w.is_finite());
    (below & above & L::splat(CERTAIN_MISS_MIN_BOUND).le(delta_e)).bitmask()
}

/// The lanes of `mask` that the lane tests hand to the scalar test: an edge function
/// within `delta_e` of zero, less the lanes of [`certain_misses`] (computed only where
/// some lane is near an edge).
#[inline(always)]
fn uncertain_edges<L: Lanes>(u: L, v: L, w: L, delta_e: L, mask: u32) -> u32 {
    let edge = (u.abs().le(delta_e) | v.abs().le(delta_e) | w.abs().le(delta_e)).bitmask() & mask;
    if edge == 0 {
        return 0;
    }
    let miss = certain_misses(u, v, w, delta_e);
    #[cfg(test)]
    NARROWED.with(|n| n.set(n.get() + (edge & miss).count_ones()));
    edge & !miss
}

// Lanes taken out of `edge` by `uncertain_edges` on this thread (for the tests).
#[cfg(test)]
thread_local! {
    static NARROWED: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// Lane twin of `geometry::triangle`'s `t_error_bound`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn t_error_bound<L: Lanes>(u: L, v: L, w: L, az: L, bz: L, cz: L, delta_e: L, rcp: L) -> L {
    let max_zt = az.abs().maxps(bz.abs()).maxps(cz.abs());
    let max_e = u.abs().maxps(v.abs()).maxps(w.abs());
    let delta_z = L::splat(err::DEPTH) * max_zt;
    L::splat(3.0)
        * (L::splat(err::DEPTH) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
        * rcp.abs()
}

/// The lane-parallel watertight test: distances, barycentrics and the hit bits.
#[inline(always)]
fn triangle4(q: &RayQuery, g: &TriGroup4, tmax: f32) -> ([f32; 4], [f32; 4], [f32; 4], u32) {
    let (kx, ky, kz) = (q.kx, q.ky, q.kz);
    let o = [
        F4::splat(q.origin.x),
        F4::splat(q.origin.y),
        F4::splat(q.origin.z),
    ];
    let corner = |c: usize, k: usize| F4::from_array(g.v[c][k]) - o[k];
    let (sx, sy, sz) = (F4::splat(q.sx), F4::splat(q.sy), F4::splat(q.sz));

    let (a_x, a_y, a_z) = (corner(0, kx), corner(0, ky), corner(0, kz));
    let (b_x, b_y, b_z) = (corner(1, kx), corner(1, ky), corner(1, kz));
    let (c_x, c_y, c_z) = (corner(2, kx), corner(2, ky), corner(2, kz));
    let ax = a_x - sx * a_z;
    let ay = a_y - sy * a_z;
    let bx = b_x - sx * b_z;
    let by = b_y - sy * b_z;
    let cx = c_x - sx * c_z;
    let cy = c_y - sy * c_z;

    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;

    let zero = F4::splat(0.0);
    let neg = u.lt(zero) | v.lt(zero) | w.lt(zero);
    let pos = u.gt(zero) | v.gt(zero) | w.gt(zero);
    let valid = g.valid_bits();
    // Lanes with an edge function within its error bound of zero: the scalar test
    // redoes those edges in f64.
    let delta_e = edge_error_bound(ax, ay, bx, by, cx, cy, a_z, b_z, c_z);
    let edge = uncertain_edges(u, v, w, delta_e, valid);
    if !(neg & pos).bitmask() & valid & !edge == 0 && edge == 0 {
        // every lane is outside its triangle: skip the division
        return ([0.0; 4], [0.0; 4], [0.0; 4], 0);
    }
    let det = u + v + w;
    let (az, bz, cz) = (sz * a_z, sz * b_z, sz * c_z);
    let t_scaled = u * az + v * bz + w * cz;
    let t = t_scaled / det;
    let rcp = F4::splat(1.0) / det;
    let delta_t = t_error_bound(u, v, w, az, bz, cz, delta_e, rcp);
    let ok = !(neg & pos).bitmask()
        & !det.eq(zero).bitmask()
        & det.is_finite().bitmask()
        & t.gt(F4::splat(q.tmin)).bitmask()
        & t.lt(F4::splat(tmax)).bitmask()
        & t.gt(delta_t).bitmask();

    let mut bits = ok & valid;
    let mut t = t.to_array();
    let mut bu = (v * rcp).to_array();
    let mut bv = (w * rcp).to_array();

    // An uncertain edge function: the scalar test redoes it in f64.
    if edge != 0 {
        edge_lanes(q, g, tmax, edge, &mut bits, &mut t, &mut bu, &mut bv);
    }
    (t, bu, bv, bits)
}

/// The scalar test for the lanes of `edge` (rare: kept out of line so the common path
/// stays small).
#[cold]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn edge_lanes(
    q: &RayQuery,
    g: &TriGroup4,
    tmax: f32,
    edge: u32,
    bits: &mut u32,
    t: &mut [f32; 4],
    bu: &mut [f32; 4],
    bv: &mut [f32; 4],
) {
    for i in 0..4 {
        if edge >> i & 1 == 1 {
            let [p0, p1, p2] = g.corners(i);
            match intersect_triangle(q, p0, p1, p2, tmax) {
                Some(h) => {
                    *bits |= 1 << i;
                    (t[i], bu[i], bv[i]) = (h.t, h.u, h.v);
                }
                None => *bits &= !(1 << i),
            }
        }
    }
}

/// The shear constants of a packet's rays for triangle tests that share one axis
/// permutation (the caller splits packets so that they do). The rays' origins and
/// interval starts are passed to the tests beside it, from where the caller keeps them:
/// a copy here (as before) was three 64-byte origin vectors and `tmin` written per
/// packet group, in 32-byte halves, and read back whole.
#[derive(Clone, Copy)]
pub struct PacketShear<L: Lanes> {
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    pub sx: L,
    pub sy: L,
    /// `-sz` (`sz = 1 / d[kz]`), for the depths of the negated corners (see
    /// [`triangle_packet`]).
    pub neg_sz: L,
}

impl<L: Lanes> PacketShear<L> {
    /// The shear of rays with directions `d` (`inv_z = 1 / d[kz]`) for the axis
    /// permutation `(kx, ky, kz)`: `RayQuery::new`'s constants, lane by lane.
    #[inline(always)]
    pub fn new(d: &[L; 3], inv_z: L, (kx, ky, kz): (usize, usize, usize)) -> Self {
        PacketShear {
            kx,
            ky,
            kz,
            sx: d[kx] * inv_z,
            sy: d[ky] * inv_z,
            neg_sz: L::splat(-1.0) * inv_z,
        }
    }
}

/// A packet (origins `o`, interval starts `tmin`, shear `p`) against triangle `lane` of
/// group `g`: `(t, u, v, hit bits)` for lanes in `active` with a hit in `(tmin, tmax)`. Lanes with an edge function within its error bound of zero
/// (exactly zero included) are returned in `edge` for the caller to redo with the
/// scalar test, which recomputes those edges in f64.
///
/// Every lane computes the scalar test's values from the corners' negated
/// translations `o - p` (the scalar test, `geometry::intersect_triangle`, computes `p -
/// o`): bit for bit their negation, as rounding to nearest is symmetric, but for the
/// sign of a zero (`x - x` is `+0` both ways). The sheared coordinates `ax .. cy` are
/// then negated too (`(-a) - s (-b)` is `-(a - s b)`), the edge functions `u, v, w` (sums
/// of products of two of them) and the depths `az, bz, cz` (taken with `-sz`) are the
/// scalar test's, again but for the signs of zeros. Those signs reach no answer: a
/// zero edge function is within its error bound, so its lane is redone by the scalar
/// test (`edge`); a nonzero sum does not depend on the signs of its zero terms, nor a
/// comparison or an absolute value on the sign of a zero; and a reported hit has `t >
/// delta_t >= 0`, so `t` and the `t_scaled` it comes from are nonzero. Why: the corner
/// is then broadcast straight from memory into the subtraction (one instruction per
/// coordinate; a broadcast can only be a subtraction's second operand), where `p - o`
/// took a broadcast and a subtraction, or with an origin shared by every lane a scalar
/// subtraction and a broadcast.
#[inline(always)]
pub fn triangle_packet<L: Lanes>(
    o: &[L; 3],
    tmin: L,
    p: &PacketShear<L>,
    g: &TriGroup4,
    lane: usize,
    tmax: L,
    active: u32,
) -> (L, L, L, u32, u32) {
    triangle_packet_by::<L>(o, tmin, p, |c, k| g.v[c][k][lane], tmax, active)
}

/// [`triangle_packet`] for a triangle given by its corners (the tiny-scene lane path,
/// `simd/tiny.rs`, whose triangles are not in leaf groups).
#[inline(always)]
pub fn triangle_packet_corners<L: Lanes>(
    o: &[L; 3],
    tmin: L,
    p: &PacketShear<L>,
    corners: &[Vec3; 3],
    tmax: L,
    active: u32,
) -> (L, L, L, u32, u32) {
    triangle_packet_by::<L>(o, tmin, p, |c, k| corners[c][k], tmax, active)
}

/// The packet triangle test with corner coordinate `k` of corner `c` read by `corner`.
#[inline(always)]
fn triangle_packet_by<L: Lanes>(
    o: &[L; 3],
    tmin: L,
    p: &PacketShear<L>,
    corner: impl Fn(usize, usize) -> f32,
    tmax: L,
    active: u32,
) -> (L, L, L, u32, u32) {
    let (kx, ky, kz) = (p.kx, p.ky, p.kz);
    // Corner coordinates read straight from the group's lane arrays. Before, the
    // corners were gathered into a `[Vec3; 3]` (`TriGroup4::corners`) and read by the
    // permuted axis through glam's `Index` (a `match` per read); callgrind of
    // `examples/stream_profile bunny.obj bvh8-packet shadow 1` (warm-up + 1 pass, same
    // checksums): `packet_any` 328.0 M -> 296.3 M instructions (-9.7 %), `packet_closest`
    // (its primary pass) 245.5 M -> 233.3 M (-5.0 %).
    // Negated: `o - p` (see `triangle_packet`).
    let rel = |c: usize, k: usize| o[k] - L::splat(corner(c, k));
    let (a_x, a_y, a_z) = (rel(0, kx), rel(0, ky), rel(0, kz));
    let (b_x, b_y, b_z) = (rel(1, kx), rel(1, ky), rel(1, kz));
    let (c_x, c_y, c_z) = (rel(2, kx), rel(2, ky), rel(2, kz));
    let ax = a_x - p.sx * a_z;
    let ay = a_y - p.sy * a_z;
    let bx = b_x - p.sx * b_z;
    let by = b_y - p.sy * b_z;
    let cx = c_x - p.sx * c_z;
    let cy = c_y - p.sy * c_z;

    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;

    let zero = L::splat(0.0);
    let delta_e = edge_error_bound(ax, ay, bx, by, cx, cy, a_z, b_z, c_z);
    let edge = uncertain_edges(u, v, w, delta_e, active);
    let neg = u.lt(zero) | v.lt(zero) | w.lt(zero);
    let pos = u.gt(zero) | v.gt(zero) | w.gt(zero);
    let inside = !(neg & pos).bitmask() & active & !edge;
    if inside == 0 {
        return (zero, zero, zero, 0, edge);
    }
    let det = u + v + w;
    let (az, bz, cz) = (p.neg_sz * a_z, p.neg_sz * b_z, p.neg_sz * c_z);
    let t_scaled = u * az + v * bz + w * cz;
    let t = t_scaled / det;
    let rcp = L::splat(1.0) / det;
    let delta_t = t_error_bound(u, v, w, az, bz, cz, delta_e, rcp);
    let bits = inside
        & !det.eq(zero).bitmask()
        & det.is_finite().bitmask()
        & t.gt(tmin).bitmask()
        & t.lt(tmax).bitmask()
        & t.gt(delta_t).bitmask();
    (t, v * rcp, w * rcp, bits, edge)
}

/// A packet's rays as lanes: origins, directions and the start of their intervals.
#[derive(Clone, Copy)]
pub struct RayLanes<L: Lanes> {
    pub o: [L; 3],
    pub d: [L; 3],
    pub tmin: L,
}

impl RayLanes<Packet> {
    /// Up to [`PACKET_WIDTH`] rays gathered into lanes, in order, with their interval
    /// ends; lanes past the last ray hold zeros.
    #[inline(always)]
    pub fn gather<'r>(rays: impl IntoIterator<Item = &'r Ray>) -> (Self, Packet) {
        let mut a = [[0.0f32; PACKET_WIDTH]; 8];
        for (i, r) in rays.into_iter().enumerate() {
            a[0][i] = r.origin.x;
            a[1][i] = r.origin.y;
            a[2][i] = r.origin.z;
            a[3][i] = r.dir.x;
            a[4][i] = r.dir.y;
            a[5][i] = r.dir.z;
            a[6][i] = r.tmin;
            a[7][i] = r.tmax;
        }
        let [ox, oy, oz, dx, dy, dz, tmin, tmax] = a.map(Packet::from_array);
        let lanes = RayLanes {
            o: [ox, oy, oz],
            d: [dx, dy, dz],
            tmin,
        };
        (lanes, tmax)
    }
}

/// A packet against one sphere: the SIMD twin of `geometry::intersect_sphere`, the
/// same operations in the same order (the negation is a multiplication by -1, which
/// keeps the sign of zero as `-x` does), so every lane equals the scalar answer.
/// Returns the nearest root in `(tmin, tmax)` per lane and the bits of the lanes of
/// `active` that have one.
#[inline(always)]
pub fn sphere_lanes<L: Lanes>(
    r: &RayLanes<L>,
    center: Vec3,
    radius: f32,
    tmax: L,
    active: u32,
) -> (L, u32) {
    let (lo, hi, roots) = roots_of::<L, true>(r, center, radius, active);
    let first = lo.gt(r.tmin) & lo.lt(tmax);
    let second = hi.gt(r.tmin) & hi.lt(tmax);
    let t = L::select(first, lo, hi);
    (t, (first | second).bitmask() & roots & active)
}

/// The two roots of every lane's ray against one sphere, in order, and the bits of the
/// lanes that have them (a real discriminant, a non-zero `q`): the scalar
/// `intersect_sphere`'s operations in its order, shared by [`sphere_lanes`] and the glass
/// crossings (`simd/glass_shadow.rs`).
#[inline(always)]
pub fn sphere_roots<L: Lanes>(r: &RayLanes<L>, center: Vec3, radius: f32) -> (L, L, u32) {
    roots_of::<L, false>(r, center, radius, u32::MAX)
}

/// [`sphere_roots`] for a caller that reads only the lanes of `active`: where none of
/// them has a real discriminant, zeros and no bits (the square root and the two
/// divisions after it skipped; see `roots_of`), else `sphere_roots`' answer.
#[inline(always)]
pub fn sphere_roots_for<L: Lanes>(
    r: &RayLanes<L>,
    center: Vec3,
    radius: f32,
    active: u32,
) -> (L, L, u32) {
    roots_of::<L, true>(r, center, radius, active)
}

/// [`sphere_roots`]; with `SKIP`, where no lane of `active` has a real discriminant,
/// zeros and no bits as soon as that is known: the square root and the two divisions
/// after it are skipped, which changes no answer (every lane's bits would have been
/// clear, and a caller reads a lane's roots only under its bit). The triangle test
/// returns early the same way (`triangle_packet_by`, no lane inside). Rays of a lane
/// group mostly pass a sphere by together (camera and reflected rays of one tile).
#[inline(always)]
fn roots_of<L: Lanes, const SKIP: bool>(
    r: &RayLanes<L>,
    center: Vec3,
    radius: f32,
    active: u32,
) -> (L, L, u32) {
    let dot = |a: &[L; 3], b: &[L; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let f = [
        r.o[0] - L::splat(center.x),
        r.o[1] - L::splat(center.y),
        r.o[2] - L::splat(center.z),
    ];
    let a = dot(&r.d, &r.d);
    let b = L::splat(-1.0) * dot(&f, &r.d);
    let ba = b / a;
    let l = [f[0] + ba * r.d[0], f[1] + ba * r.d[1], f[2] + ba * r.d[2]];
    let r2 = L::splat(radius * radius);
    let disc = a * (r2 - dot(&l, &l));
    let real = L::splat(0.0).le(disc).bitmask(); // false for NaN, as in the scalar test
    if SKIP && real & active == 0 {
        let zero = L::splat(0.0);
        return (zero, zero, 0);
    }
    let c = dot(&f, &f) - r2;
    // copysign(sqrt(disc), b): the root is +0 or positive, so OR-ing b's sign bit in is exact.
    let q = b + (disc.sqrt() | (b & L::splat(-0.0)));
    let nonzero = !q.eq(L::splat(0.0)).bitmask();
    let (t0, t1) = (c / q, q / a);
    let swap = t0.gt(t1);
    let (lo, hi) = (L::select(swap, t1, t0), L::select(swap, t0, t1));
    (lo, hi, real & nonzero)
}

/// The constants of glibc's `sincosf` (`sysdeps/ieee754/flt-32/s_sincosf_data.c`,
/// `__sincosf_table`, from Arm's optimized-routines): `2/π · 2^24`, `π/2`, the cosine
/// polynomial `c0..c4` of the first table (the second, used in quadrants 2 and 3, is
/// its negation) and the sine polynomial `s1..s3` (the same in both).
mod glibc_sincosf {
    pub const HPI_INV: f64 = f64::from_bits(0x4164_5f30_6dc9_c883);
    pub const HPI: f64 = f64::from_bits(0x3ff9_21fb_5444_2d18);
    pub const C: [f64; 5] = [
        1.0,
        f64::from_bits(0xbfdf_ffff_fd0c_621c),
        f64::from_bits(0x3fa5_5553_e106_8f19),
        f64::from_bits(0xbf56_c087_e89a_359d),
        f64::from_bits(0x3ef9_9343_027b_f8c3),
    ];
    pub const S: [f64; 3] = [
        f64::from_bits(0xbfc5_5554_5995_a603),
        f64::from_bits(0x3f81_1076_0523_0bc4),
        f64::from_bits(0xbf29_94eb_3774_cf24),
    ];
}

/// `(sin y, cos y)` of one `f32` as glibc 2.36's `sincosf` computes them in its FMA
/// build (`__sincosf_fma`, which libm picks on this AVX-512 machine), for `|y| < 120`
/// (the range of its fast reduction), written branch-free so that sixteen lanes of it
/// vectorise ([`sin_cos_libm16`]). The same operations in the same order, each `a + b
/// c` of `sincosf_poly` one fused multiply-add as the FMA build compiles it (read
/// from its disassembly): `|y| < 2^-12` returns `(y, 1)`; below the top-12-bits bound
/// of `π/4` the polynomials run on `y` itself; above it `y` is reduced by the nearest
/// multiple `n` of `π/2` (`n` from `y · 2/π · 2^24` truncated, plus `2^23`, shifted
/// down by 24) and the quadrant picks the sign of the sine, the cosine table's sign and
/// whether sine and cosine swap.
///
/// # Safety
/// `|y| < 120` (not NaN): `y · 2/π · 2^24` then fits an `i32`, which its unchecked
/// truncation needs (a checked cast would not vectorise).
#[cfg(target_feature = "fma")]
#[inline(always)]
unsafe fn sin_cos_libm_one(y: f32) -> (f32, f32) {
    use glibc_sincosf::{C, HPI, HPI_INV, S};
    let top = (y.to_bits() >> 20) & 0x7ff;
    let x = y as f64;
    let reduce = top > 0x3f3;
    // SAFETY: `|x| < 120`, so `|x 2/π 2^24| < 2^31` (the caller's contract); the
    // truncation is then `cvttsd2si`'s, as libm's.
    let n = if reduce {
        unsafe { (x * HPI_INV).to_int_unchecked::<i32>() }.wrapping_add(0x80_0000) >> 24
    } else {
        0
    };
    let xr = if reduce {
        (-(n as f64)).mul_add(HPI, x)
    } else {
        x
    };
    let sign = if (n + 1) & 2 != 0 { -1.0 } else { 1.0 };
    let neg = if n & 2 != 0 { -1.0 } else { 1.0 };
    let xs = xr * sign;
    let x2 = xr * xr;
    let x3 = x2 * xs;
    let x4 = x2 * x2;
    let x5 = x2 * x3;
    let x6 = x2 * x4;
    let s13 = x2.mul_add(S[2], S[1]);
    let c34 = x2.mul_add(neg * C[4], neg * C[3]);
    let c01 = x2.mul_add(neg * C[1], neg * C[0]);
    let s = x5.mul_add(s13, x3.mul_add(S[0], xs)) as f32;
    let c = x6.mul_add(c34, x4.mul_add(neg * C[2], c01)) as f32;
    let (s, c) = if n & 1 != 0 { (c, s) } else { (s, c) };
    if top <= 0x397 { (y, 1.0) } else { (s, c) }
}

/// `(sin y, cos y)` per lane, bit for bit what libm's `sincosf` (`f32::sin`,
/// `f32::cos`, which the compiler merges into one `sincosf` call) returns here: with
/// FMA, [`sin_cos_libm_one`] in lanes for arguments `|y| < 120` (any other lane sends
/// the whole call to libm); without FMA, libm lane by lane.
///
/// Why (issue 12, pk26): the diffuse rays of `bench` need `cos 2πu` and `sin 2πu` per
/// ray, and libm's call per lane was 6.1 % of a bunny diffuse pass (`perf record` of
/// `examples/stream_profile bunny.obj bvh8-stream diffuse 40`, AVX-512), about 10 ns
/// a ray. The rays must stay the scalar protocol's bit for bit (the checksums are
/// compared with every earlier run); the test holds this to libm over every argument
/// `2π · k 2^-24` the protocol makes (`k < 2^24`) and a sweep of `[-120, 120]`.
#[inline(always)]
pub fn sin_cos_libm16(y: &[f32; 16]) -> ([f32; 16], [f32; 16]) {
    let (mut s, mut c) = ([0.0f32; 16], [0.0f32; 16]);
    // Every lane checked (no early exit, so the check stays in lanes too).
    #[cfg(target_feature = "fma")]
    if y.iter().fold(true, |all, v| all & (v.abs() < 120.0)) {
        for k in 0..16 {
            // SAFETY: every lane is below 120 in magnitude (and not NaN).
            (s[k], c[k]) = unsafe { sin_cos_libm_one(y[k]) };
        }
        return (s, c);
    }
    for k in 0..16 {
        (s[k], c[k]) = (y[k].sin(), y[k].cos());
    }
    (s, c)
}

#[cfg(test)]
mod sin_cos_libm_tests {
    use super::*;
    use std::hint::black_box;

    /// `sin_cos_libm16` of sixteen arguments against libm's `sin` and `cos` of each,
    /// bit for bit; returns how many lanes took the lane path's reduction (`|y| >= 0.75`).
    fn check(y: &[f32; 16]) -> usize {
        let (s, c) = sin_cos_libm16(y);
        for k in 0..16 {
            let v = black_box(y[k]);
            let (ws, wc) = (v.sin(), v.cos());
            assert_eq!(
                (s[k].to_bits(), c[k].to_bits()),
                (ws.to_bits(), wc.to_bits()),
                "y = {:e} ({:#x}): lanes ({:e}, {:e}), libm ({ws:e}, {wc:e})",
                y[k],
                y[k].to_bits(),
                s[k],
                c[k]
            );
        }
        y.iter().filter(|v| v.abs() >= 0.75).count()
    }

    /// Every argument the bench's diffuse rays make, `(2π as f32) · k 2^-24` for `k <
    /// 2^24` (the top 24 bits of a draw), and a sweep of the whole fast range `|y| <
    /// 120` in both signs (every 61st bit pattern, so every exponent and the bounds
    /// between the tiny, polynomial and reduced paths), with the bounds themselves,
    /// zeros, subnormals and arguments outside the range (libm's own path): the same bits
    /// as libm.
    #[test]
    fn lanes_are_libm_bit_for_bit() {
        let two_pi = (2.0 * std::f64::consts::PI) as f32;
        let mut y = [0.0f32; 16];
        let mut reduced = 0;
        for k in 0..1u32 << 24 {
            y[(k % 16) as usize] = two_pi * (k as f32 * (1.0 / 16_777_216.0));
            if k % 16 == 15 {
                reduced += check(&y);
            }
        }
        let top = 120.0f32.to_bits();
        let mut i = 0;
        for bits in (0..top).step_by(61).chain([top - 1, top, top + 1]) {
            for v in [f32::from_bits(bits), -f32::from_bits(bits)] {
                y[i % 16] = v;
                i += 1;
                if i % 16 == 0 {
                    reduced += check(&y);
                }
            }
        }
        let specials = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-40,
            -1e-40,
            f32::from_bits(0x3980_0000),
            f32::from_bits(0x397f_ffff),
            f32::from_bits(0x3f40_0000),
            f32::from_bits(0x3f3f_ffff),
            std::f32::consts::FRAC_PI_4,
            std::f32::consts::PI,
            -119.99999,
            119.99999,
            1e30,
            f32::INFINITY,
            f32::NAN,
        ];
        check(&specials);
        // Sixteen in range (the lane path) with the same edge values.
        let mut in_range = specials;
        in_range[13..].copy_from_slice(&[2.5, -3.75, 100.0]);
        check(&in_range);
        assert!(reduced > 10_000_000, "{reduced} lanes took the reduction");
    }
}

#[cfg(test)]
mod tri_group_tests {
    use super::*;

    /// Every pattern of used and unused lanes (ids around `u32::MAX` and `i32::MAX`,
    /// which the lane compare reads as signed): the bits of the lanes whose id is not
    /// `u32::MAX`.
    #[test]
    fn valid_bits_marks_the_lanes_with_a_triangle() {
        let used = [0, 7, i32::MAX as u32, 1 << 31, u32::MAX - 1];
        for pattern in 0..16u32 {
            for (k, &id) in used.iter().enumerate() {
                let mut g = TriGroup4::EMPTY;
                for lane in 0..4 {
                    if pattern >> lane & 1 == 1 {
                        g.ids[lane] = id.wrapping_add(lane as u32 * k as u32);
                    }
                }
                assert_eq!(g.valid_bits(), pattern, "{:?}", g.ids);
            }
        }
    }
}

#[cfg(test)]
mod triangle_packet_tests {
    use super::*;
    use crate::simd::F16;

    /// Sixteen rays as the packet test takes them, with their scalar queries.
    struct InLanes {
        queries: [RayQuery; 16],
        /// The first query's axis permutation.
        perm: (usize, usize, usize),
        o: [F16; 3],
        shear: PacketShear<F16>,
        tmin: F16,
        tmax: F16,
    }

    /// Asserts that a lane's answer (its hit bit, and for a hit `t`, `u`, `v` bit for bit)
    /// is the scalar test's; `at` names the lane in a failure. Returns whether it hit.
    fn assert_lane_answer(
        hit: bool,
        tuv: [f32; 3],
        scalar: Option<PrimHit>,
        at: impl Fn() -> String,
    ) -> bool {
        assert_eq!(hit, scalar.is_some(), "{}", at());
        if let Some(h) = scalar {
            assert_eq!(
                tuv.map(f32::to_bits),
                [h.t, h.u, h.v].map(f32::to_bits),
                "{}",
                at()
            );
        }
        scalar.is_some()
    }

    /// `rays` in lanes, sheared for the permutation of the first ray's query with the
    /// depth axis `kz`.
    fn in_lanes(rays: &[Ray; 16], kz: usize) -> InLanes {
        let queries = rays.map(|r| RayQuery::new(&r).expect("valid ray"));
        let perm = (queries[0].kx, queries[0].ky, queries[0].kz);
        let lanes = |f: &dyn Fn(&Ray) -> f32| F16::from_array(rays.each_ref().map(f));
        let d = [0, 1, 2].map(|a| lanes(&|r| r.dir[a]));
        InLanes {
            queries,
            perm,
            o: [0, 1, 2].map(|a| lanes(&|r| r.origin[a])),
            shear: PacketShear::new(&d, F16::splat(1.0) / d[kz], perm),
            tmin: lanes(&|r| r.tmin),
            tmax: lanes(&|r| r.tmax),
        }
    }

    /// The packet triangle test (negated translations, `triangle_packet`) against the
    /// scalar watertight test, lane by lane, where the signs of zeros are at stake:
    /// corners and origins on a coarse grid of halves (so `p - o`, the sheared
    /// coordinates and the edge functions are often exactly zero), origins with `-0.0`
    /// and `+0.0` components mixed in one packet, directions along an axis and on
    /// diagonals. Every lane the test does not hand back as `edge` must give the scalar
    /// answer: hit or miss, and `t`, `u`, `v` bit for bit.
    #[test]
    fn packet_triangle_test_is_the_scalar_test_bit_for_bit() {
        let mut s = 0x2545_f491u32;
        let mut next = move |n: u32| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s % n
        };
        // -2, -1.5, .., 2, with both zeros
        let grid = move |r: &mut dyn FnMut(u32) -> u32| match r(10) {
            9 => -0.0f32,
            k => (k as f32 - 4.0) * 0.5,
        };
        let (mut compared, mut hits, mut zero_sign_lanes) = (0u32, 0u32, 0u32);
        for trial in 0..20_000 {
            let corners: [Vec3; 3] = std::array::from_fn(|_| {
                Vec3::new(grid(&mut next), grid(&mut next), grid(&mut next))
            });
            // One direction family per packet (a shared permutation), each lane's
            // direction nudged off it; origins shared (with mixed zero signs) or not.
            let kz = next(3) as usize;
            let sign = if next(2) == 0 { 1.0 } else { -1.0 };
            let shared = trial % 2 == 0;
            let base = Vec3::new(grid(&mut next), grid(&mut next), grid(&mut next));
            let rays: [Ray; 16] = std::array::from_fn(|i| {
                let mut d = [0.0f32; 3];
                d[kz] = sign * 4.0;
                for (a, x) in d.iter_mut().enumerate() {
                    if a != kz {
                        *x = (next(7) as f32 - 3.0) * [0.0, 0.5, 1.0][(i + a) % 3];
                    }
                }
                let mut o = if shared {
                    base
                } else {
                    Vec3::new(grid(&mut next), grid(&mut next), grid(&mut next))
                };
                // the zero of a shared origin's component in either sign
                for a in 0..3 {
                    if o[a] == 0.0 && next(2) == 0 {
                        o[a] = -o[a];
                    }
                }
                o[kz] -= sign * 3.0;
                let tmax = [f32::INFINITY, 2.0, 0.5][i % 3];
                Ray::segment(o, Vec3::from_array(d), 0.0, tmax)
            });
            let InLanes {
                queries,
                perm,
                o,
                shear,
                tmin,
                tmax,
            } = in_lanes(&rays, kz);
            let active = 0xffff;
            let (t, u, v, bits, edge) =
                triangle_packet_corners(&o, tmin, &shear, &corners, tmax, active);
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            for (i, q) in queries.iter().enumerate() {
                assert_eq!((q.kx, q.ky, q.kz), perm);
                if edge >> i & 1 == 1 {
                    assert_eq!(bits >> i & 1, 0, "an edge lane is left to the scalar test");
                    continue;
                }
                compared += 1;
                let [p0, p1, p2] = corners;
                zero_sign_lanes +=
                    u32::from((0..3).any(|a| corners.iter().any(|c| c[a] == q.origin[a])));
                let scalar = intersect_triangle(q, p0, p1, p2, q.tmax);
                let tuv = [t[i], u[i], v[i]];
                if assert_lane_answer(bits >> i & 1 == 1, tuv, scalar, || {
                    format!("trial {trial} lane {i}")
                }) {
                    hits += 1;
                }
            }
        }
        assert!(
            hits > 10_000 && zero_sign_lanes > 100_000,
            "too few cases: {hits} hits, {zero_sign_lanes} lanes with a zero translation of {compared}"
        );
    }

    /// Rays aimed at points on the lines through a triangle's edges (on the edges, at
    /// the corners and past them, where the other two edge functions have clear
    /// opposite signs), in packets sharing an origin or not, with finite and short
    /// intervals: the packet test (group form, as the BVH kernels run it) and the
    /// single-ray `triangle4` give the scalar watertight test's answer for every lane
    /// they decide (hit or miss, `t`, `u`, `v` bit for bit), hand no hit back with an
    /// `edge` lane, and decide many lanes through `certain_misses` (counted), so the
    /// narrowing is exercised and exact on the rays it exists for.
    #[test]
    fn lanes_near_edge_lines_are_the_scalar_answers() {
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut r = move || (next() >> 40) as f32 / (1u32 << 24) as f32;
        NARROWED.with(|n| n.set(0));
        let (mut decided, mut hits, mut edge_lanes, mut on_lines) = (0u32, 0u32, 0u32, 0u32);
        for trial in 0..3000 {
            let mut g = TriGroup4::EMPTY;
            for lane in 0..4 {
                let c = std::array::from_fn(|_| Vec3::new(r(), r(), r()) * 2.0 - Vec3::ONE);
                g.set(lane, lane as u32, c);
            }
            let lane = trial % 4;
            let [p0, p1, p2] = g.corners(lane);
            let kz = trial % 3;
            let sign = if trial % 7 < 3 { -1.0 } else { 1.0 };
            let mut base = Vec3::new(r(), r(), r()) * 2.0 - Vec3::ONE;
            base[kz] = -sign * 20.0;
            let rays: [Ray; 16] = std::array::from_fn(|i| {
                let (a, b) = [(p0, p1), (p1, p2), (p2, p0)][(i + trial) % 3];
                let s = [-1.5, -0.25, 0.0, 0.5, 1.0, 1.3, 2.5, r() * 4.0 - 1.5][i % 8];
                // and every eighth ray at a point inside the triangle, for hits
                let aim = if i % 8 == 7 {
                    let (x, y) = (r() * 0.5, r() * 0.5);
                    p0 + (p1 - p0) * x + (p2 - p0) * y
                } else {
                    a + (b - a) * s
                };
                let o = if trial % 2 == 0 {
                    base
                } else {
                    let mut o = base + Vec3::new(r(), r(), r());
                    o[kz] = base[kz];
                    o
                };
                let tmax = [f32::INFINITY, 40.0, 19.0 + r() * 2.0][i % 3];
                Ray::segment(o, aim - o, 0.0, tmax)
            });
            let InLanes {
                queries,
                perm,
                o,
                shear,
                tmin,
                tmax,
            } = in_lanes(&rays, kz);
            let (t, u, v, bits, edge) = triangle_packet(&o, tmin, &shear, &g, lane, tmax, 0xffff);
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            for (i, q) in queries.iter().enumerate() {
                assert_eq!((q.kx, q.ky, q.kz), perm, "trial {trial}: one permutation");
                on_lines += 1;
                let scalar = intersect_triangle(q, p0, p1, p2, q.tmax);
                if edge >> i & 1 == 1 {
                    edge_lanes += 1;
                    assert_eq!(bits >> i & 1, 0, "an edge lane is left to the scalar test");
                } else {
                    decided += 1;
                    let tuv = [t[i], u[i], v[i]];
                    if assert_lane_answer(bits >> i & 1 == 1, tuv, scalar, || {
                        format!("trial {trial} lane {i}")
                    }) {
                        hits += 1;
                    }
                }
                // The single-ray test of the whole group, each lane against the oracle.
                let (t4, u4, v4, bits4) = triangle4(q, &g, q.tmax);
                for k in 0..4 {
                    let [c0, c1, c2] = g.corners(k);
                    let want = intersect_triangle(q, c0, c1, c2, q.tmax);
                    assert_lane_answer(bits4 >> k & 1 == 1, [t4[k], u4[k], v4[k]], want, || {
                        format!("trial {trial} ray {i} lane {k}")
                    });
                }
            }
        }
        let narrowed = NARROWED.with(|n| n.get());
        assert!(
            narrowed > on_lines / 2 && hits > on_lines / 20 && decided > on_lines / 2,
            "too few cases: {narrowed} lanes narrowed, {hits} hits, {decided} decided, \
             {edge_lanes} edge lanes of {on_lines}"
        );
    }
}
