use crate::simd::{Lanes, PACKET_WIDTH};
use glam::Vec3;

/// A ray with its parametric interval `[tmin, tmax]` and a time in the shutter interval
/// (0 for scenes without motion).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
    pub time: f32,
}

impl Ray {
    /// Every field's bits (origin, direction, then `tmin`, `tmax`, `time`): what the
    /// bit-for-bit tests compare.
    #[cfg(test)]
    pub(crate) fn bits(&self) -> [[u32; 3]; 3] {
        [
            self.origin.to_array(),
            self.dir.to_array(),
            [self.tmin, self.tmax, self.time],
        ]
        .map(|a| a.map(f32::to_bits))
    }

    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
            time: 0.0,
        }
    }

    pub fn segment(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Ray {
            origin,
            dir,
            tmin,
            tmax,
            time: 0.0,
        }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// A ray that can hit anything: finite origin and direction, a non-zero direction
    /// and a non-empty interval. Invalid rays (NaN, inf, zero direction) miss everything.
    ///
    /// Branch-free: `x * 0` is ±0 for a finite `x` and NaN for an infinite or NaN one, so
    /// the six products sum to 0 exactly when origin and direction are finite; `tmin <=
    /// tmax` is false when either is NaN.
    #[inline]
    pub fn is_valid(&self) -> bool {
        let finite = self.origin * 0.0 + self.dir * 0.0;
        (finite.x + finite.y + finite.z == 0.0)
            & (self.dir != Vec3::ZERO)
            & (self.tmin <= self.tmax)
    }
}

/// Up to [`PACKET_WIDTH`] rays as structure of arrays (the layout of Embree's
/// `RTCRay16`): the packet kernels load each field as one lane vector, so a caller that
/// generates rays lane-parallel (camera rays) can hand them over without a transpose.
/// Lanes `len..` are unused and ignored.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct RayPacket {
    pub origin: [[f32; PACKET_WIDTH]; 3],
    pub dir: [[f32; PACKET_WIDTH]; 3],
    pub tmin: [f32; PACKET_WIDTH],
    pub tmax: [f32; PACKET_WIDTH],
    pub time: [f32; PACKET_WIDTH],
    pub len: usize,
}

impl Default for RayPacket {
    fn default() -> Self {
        RayPacket {
            origin: [[0.0; PACKET_WIDTH]; 3],
            dir: [[0.0; PACKET_WIDTH]; 3],
            tmin: [0.0; PACKET_WIDTH],
            tmax: [0.0; PACKET_WIDTH],
            time: [0.0; PACKET_WIDTH],
            len: 0,
        }
    }
}

impl RayPacket {
    /// A packet of `rays` (at most [`PACKET_WIDTH`]).
    pub fn from_rays(rays: &[Ray]) -> Self {
        assert!(rays.len() <= PACKET_WIDTH, "more rays than packet lanes");
        let mut p = RayPacket::default();
        for (i, r) in rays.iter().enumerate() {
            p.set(i, r);
        }
        p.len = rays.len();
        p
    }

    /// Writes `r` into lane `i` (which must be below [`PACKET_WIDTH`]; `len` is not
    /// changed).
    #[inline]
    pub fn set(&mut self, i: usize, r: &Ray) {
        for a in 0..3 {
            self.origin[a][i] = r.origin[a];
            self.dir[a][i] = r.dir[a];
        }
        self.tmin[i] = r.tmin;
        self.tmax[i] = r.tmax;
        self.time[i] = r.time;
    }

    /// Appends `r`; the packet must not be full.
    #[inline]
    pub fn push(&mut self, r: &Ray) {
        self.set(self.len, r);
        self.len += 1;
    }

    /// The ray of lane `i`.
    #[inline]
    pub fn ray(&self, i: usize) -> Ray {
        let v = |a: &[[f32; PACKET_WIDTH]; 3]| Vec3::new(a[0][i], a[1][i], a[2][i]);
        Ray {
            origin: v(&self.origin),
            dir: v(&self.dir),
            tmin: self.tmin[i],
            tmax: self.tmax[i],
            time: self.time[i],
        }
    }
}

/// The rays of one packet as the packet kernels read them: either a slice of rays (the
/// batch entry points) or a [`RayPacket`]. The kernels are generic over it, so neither
/// form is converted into the other: a slice is gathered into lanes once, a packet is
/// loaded as it is, and a lane that falls back to the scalar path reads its ray from
/// where it already lies.
pub trait LaneRays {
    /// Rays present (at most [`PACKET_WIDTH`]); lanes past it are ignored.
    fn lane_count(&self) -> usize;
    /// Origin x/y/z, direction x/y/z, tmin, tmax as lanes (unused lanes: anything).
    fn load_lanes<L: Lanes>(&self) -> [L; 8];
    /// The origin of lane `i`.
    fn lane_origin(&self, i: usize) -> [f32; 3];
    /// The query of lane `i`; `None` for an invalid ray.
    fn lane_query(&self, i: usize) -> Option<RayQuery>;
}

impl LaneRays for [Ray] {
    #[inline(always)]
    fn lane_count(&self) -> usize {
        self.len()
    }
    #[inline(always)]
    fn load_lanes<L: Lanes>(&self) -> [L; 8] {
        let mut a = [L::splat(0.0).to_array(); 8];
        for (i, r) in self.iter().enumerate().take(L::WIDTH) {
            let vals = [
                r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax,
            ];
            for (k, v) in vals.into_iter().enumerate() {
                a[k].as_mut()[i] = v;
            }
        }
        a.map(L::from_array)
    }
    #[inline(always)]
    fn lane_origin(&self, i: usize) -> [f32; 3] {
        self[i].origin.to_array()
    }
    #[inline(always)]
    fn lane_query(&self, i: usize) -> Option<RayQuery> {
        RayQuery::new(&self[i])
    }
}

impl LaneRays for RayPacket {
    #[inline(always)]
    fn lane_count(&self) -> usize {
        self.len
    }
    #[inline(always)]
    fn load_lanes<L: Lanes>(&self) -> [L; 8] {
        [
            L::load(&self.origin[0]),
            L::load(&self.origin[1]),
            L::load(&self.origin[2]),
            L::load(&self.dir[0]),
            L::load(&self.dir[1]),
            L::load(&self.dir[2]),
            L::load(&self.tmin),
            L::load(&self.tmax),
        ]
    }
    #[inline(always)]
    fn lane_origin(&self, i: usize) -> [f32; 3] {
        [self.origin[0][i], self.origin[1][i], self.origin[2][i]]
    }
    #[inline(always)]
    fn lane_query(&self, i: usize) -> Option<RayQuery> {
        RayQuery::new(&self.ray(i))
    }
}

/// A ray prepared for traversal: the reciprocal direction for slab tests and the
/// shear constants of the watertight triangle test (Woop, Benthin, Wald 2013), computed
/// once per ray instead of once per primitive.
#[derive(Clone, Copy, Debug)]
pub struct RayQuery {
    pub origin: Vec3,
    pub dir: Vec3,
    /// 1/dir per component. A +0.0 or -0.0 component gives +inf or -inf, which the slab
    /// test handles (the interval is then the whole line or empty), never NaN unless the
    /// origin lies exactly on the slab plane; see `Aabb::intersect`.
    pub inv_dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
    pub time: f32,
    /// Axis permutation: `kz` is the dominant direction axis.
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    /// Shear constants: `sx = d[kx]/d[kz]`, `sy = d[ky]/d[kz]`, `sz = 1/d[kz]`.
    pub sx: f32,
    pub sy: f32,
    pub sz: f32,
}

impl RayQuery {
    /// Prepares a ray; `None` for an invalid ray (it can hit nothing).
    ///
    /// Written for the per-ray cost of the single-ray and stream kernels (callgrind of
    /// the AVX2 build put the former form at 109 instructions a ray: glam's `Index`
    /// is a `match` per read, `(kz + 1) % 3` two divisions' worth, the validity checks
    /// branch by branch): components are read from arrays, the permutation from a
    /// table, and `sz` is the reciprocal's `kz` component (`1.0 / d[kz]` either way,
    /// the same correctly rounded division).
    #[inline]
    pub fn new(ray: &Ray) -> Option<Self> {
        ray.is_valid().then(|| Self::of_valid(ray))
    }

    /// [`RayQuery::new`] of a ray known to be valid, always inlined: the stream
    /// kernel's binning builds each query straight into its bin slot with it (a call
    /// returning the `Option` through memory cost failed store forwards there).
    #[inline(always)]
    pub fn of_valid(ray: &Ray) -> Self {
        /// The axis after `k`, cyclically, and the one after that.
        const NEXT: [[usize; 2]; 3] = [[1, 2], [2, 0], [0, 1]];
        let d = ray.dir.to_array();
        let inv_dir = Vec3::ONE / ray.dir;
        let kz = dominant_axis(ray.dir);
        let [a, b] = NEXT[kz];
        // Keep the winding of the projected triangle: swap when the dominant axis is negative.
        let (kx, ky) = if d[kz] < 0.0 { (b, a) } else { (a, b) };
        let sz = inv_dir.to_array()[kz];
        RayQuery {
            origin: ray.origin,
            dir: ray.dir,
            inv_dir,
            tmin: ray.tmin,
            tmax: ray.tmax,
            time: ray.time,
            kx,
            ky,
            kz,
            sx: d[kx] * sz,
            sy: d[ky] * sz,
            sz,
        }
    }
}

/// The direction octant of `d`: bit `a` set where component `a` has its sign bit set
/// (-0.0 counts as negative, as the slab test's near/far choice does). Stream binning
/// and packet grouping key rays by it.
#[inline]
pub fn octant(d: Vec3) -> usize {
    (d.x.is_sign_negative() as usize)
        | (d.y.is_sign_negative() as usize) << 1
        | (d.z.is_sign_negative() as usize) << 2
}

/// The axis along which `d` is largest in magnitude (ties to the lower axis): the
/// watertight test's `kz`. Packet setup groups lanes by it, and the stream kernel's
/// coherence test (`bvhn::prefers_stream`) predicts that grouping with it.
#[inline]
pub fn dominant_axis(d: Vec3) -> usize {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The query as first written (glam's `Index`, `% 3`, the validity checks one by
    /// one): the oracle of the branch-free [`RayQuery::new`].
    fn reference(ray: &Ray) -> Option<[u32; 16]> {
        let valid = ray.origin.is_finite()
            && ray.dir.is_finite()
            && ray.dir != Vec3::ZERO
            && !ray.tmin.is_nan()
            && !ray.tmax.is_nan()
            && ray.tmin <= ray.tmax;
        if !valid {
            return None;
        }
        let d = ray.dir;
        let kz = dominant_axis(d);
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / d[kz];
        let inv = Vec3::ONE / d;
        let f = |x: f32| x.to_bits();
        Some([
            f(inv.x),
            f(inv.y),
            f(inv.z),
            f(ray.tmin),
            f(ray.tmax),
            f(ray.time),
            kx as u32,
            ky as u32,
            kz as u32,
            f(d[kx] * sz),
            f(d[ky] * sz),
            f(sz),
            f(ray.origin.x),
            f(ray.origin.y),
            f(ray.origin.z),
            f(d.x) ^ f(d.y) ^ f(d.z),
        ])
    }

    fn fields(q: &RayQuery) -> [u32; 16] {
        let f = |x: f32| x.to_bits();
        [
            f(q.inv_dir.x),
            f(q.inv_dir.y),
            f(q.inv_dir.z),
            f(q.tmin),
            f(q.tmax),
            f(q.time),
            q.kx as u32,
            q.ky as u32,
            q.kz as u32,
            f(q.sx),
            f(q.sy),
            f(q.sz),
            f(q.origin.x),
            f(q.origin.y),
            f(q.origin.z),
            f(q.dir.x) ^ f(q.dir.y) ^ f(q.dir.z),
        ]
    }

    /// Every combination of special and ordinary components (signed zeros, ties for the
    /// dominant axis, infinities, NaN, subnormals) and of special intervals: the same
    /// verdict and, for valid rays, the same fields bit for bit as the reference.
    #[test]
    fn query_matches_the_reference_formulation() {
        let comps = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -2.0,
            1e-40,
            -3e38,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let intervals = [
            (0.0, f32::INFINITY),
            (1.0, 1.0),
            (2.0, 1.0),
            (f32::NAN, 1.0),
            (0.0, f32::NAN),
            (-1.0, 5.0),
            (f32::NEG_INFINITY, f32::INFINITY),
        ];
        let (mut valid, mut invalid) = (0, 0);
        for &x in &comps {
            for &y in &comps {
                for &z in &comps {
                    for (i, &(tmin, tmax)) in intervals.iter().enumerate() {
                        // Directions over all of `comps`; origins from a rotation of the
                        // same components, so that non-finite origins occur too.
                        let dir = Vec3::new(x, y, z);
                        let origin = Vec3::new(z, x, comps[i]);
                        let ray = Ray {
                            origin,
                            dir,
                            tmin,
                            tmax,
                            time: 0.25,
                        };
                        let want = reference(&ray);
                        assert_eq!(ray.is_valid(), want.is_some(), "{ray:?}");
                        let got = RayQuery::new(&ray).map(|q| fields(&q));
                        assert_eq!(got, want, "{ray:?}");
                        if want.is_some() {
                            valid += 1;
                        } else {
                            invalid += 1;
                        }
                    }
                }
            }
        }
        // Both verdicts are exercised.
        assert!(
            valid > 1000 && invalid > 1000,
            "{valid} valid, {invalid} invalid"
        );
    }
}
