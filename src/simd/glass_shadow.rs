//! Transmitted shadow rays through glass spheres in lanes: how many times each ray
//! crosses a sphere's surface inside its interval, which is how many times the filtered
//! query (`accel::filter`, `sphere_candidates`) would offer that sphere to the
//! transmittance filter (`integrator::shadow`).
//!
//! The roots are [`super::kernels::sphere_lanes`]'s arithmetic (the lane
//! twin of `geometry::intersect_sphere`, bit for bit), and the count follows
//! `sphere_candidates` exactly: the nearest root in `(tmin, tmax)`, then the far root if
//! it lies beyond the near one and before `tmax` (the scalar code re-runs the test with
//! `tmin` moved to the first root, which computes the same two roots).

use super::kernels::{RayLanes, sphere_lanes, sphere_roots};
use super::{Lanes, PACKET_WIDTH, Packet};
use crate::geometry::Ray;
use glam::Vec3;

/// The crossings of the lanes in `active` with one sphere: `(once, twice)`, the bits of
/// the lanes with at least one candidate and of those with two.
#[inline(always)]
pub fn sphere_crossings<L: Lanes>(
    r: &RayLanes<L>,
    center: Vec3,
    radius: f32,
    tmax: L,
    active: u32,
) -> (u32, u32) {
    crossings_of_roots(r, sphere_roots(r, center, radius), tmax, active)
}

/// One sphere's roots of a lane group (`kernels::sphere_roots`: nearer root, farther
/// root, the bits of the lanes that have them), computed once and read by both
/// [`meets_of_roots`] and [`crossings_of_roots`] (the lane-settled quad-light shadows:
/// which lanes meet a sphere, then how many times the glass ones cross it).
pub type SphereRoots<L> = (L, L, u32);

/// [`sphere_lanes`]`(r, centre, radius, tmax, active).1` from the sphere's roots
/// `(lo, hi, roots)` (`sphere_roots(r, centre, radius)`): the same operations on the
/// same values.
#[inline(always)]
pub fn meets_of_roots<L: Lanes>(
    r: &RayLanes<L>,
    (lo, hi, roots): SphereRoots<L>,
    tmax: L,
    active: u32,
) -> u32 {
    let first = lo.gt(r.tmin) & lo.lt(tmax);
    let second = hi.gt(r.tmin) & hi.lt(tmax);
    (first | second).bitmask() & roots & active
}

/// [`sphere_crossings`] from the sphere's roots (`sphere_roots(r, centre, radius)`).
#[inline(always)]
pub fn crossings_of_roots<L: Lanes>(
    r: &RayLanes<L>,
    (lo, hi, roots): SphereRoots<L>,
    tmax: L,
    active: u32,
) -> (u32, u32) {
    let hits = roots & active;
    let first = (lo.gt(r.tmin) & lo.lt(tmax)).bitmask();
    let second = (hi.gt(r.tmin) & hi.lt(tmax)).bitmask();
    let beyond = (hi.gt(lo) & hi.lt(tmax)).bitmask();
    ((first | second) & hits, first & beyond & hits)
}

/// The number of candidates each of `rays` (at most [`PACKET_WIDTH`], all valid)
/// meets over `spheres` (centre, radius) in its interval `(tmin, tmax)`: what the
/// filtered query offers a filter that rejects every candidate.
pub fn crossing_counts(rays: &[Ray], spheres: &[(Vec3, f32)]) -> [u32; PACKET_WIDTH] {
    settle_lanes(rays, &[], spheres).1
}

/// `(blocked, counts)` for `rays` (at most [`PACKET_WIDTH`], all valid): the bits of
/// the rays that one of the `opaque` spheres blocks (`intersect_sphere` in the
/// interval, as an any-hit query), and for the others [`crossing_counts`] over
/// `glass` (zero for a blocked ray).
pub fn settle_lanes(
    rays: &[Ray],
    opaque: &[(Vec3, f32)],
    glass: &[(Vec3, f32)],
) -> (u32, [u32; PACKET_WIDTH]) {
    debug_assert!(rays.len() <= PACKET_WIDTH);
    let (lanes, tmax) = RayLanes::gather(rays.iter().inspect(|r| debug_assert!(r.is_valid())));
    let all = ((1u64 << rays.len()) - 1) as u32;
    settle_gathered(&lanes, tmax, all, opaque, glass)
}

/// [`settle_lanes`] of rays already in lanes (`lanes`, interval ends `tmax`), for the
/// lanes in `live` (all valid rays): the bits of those an `opaque` sphere blocks, and
/// for the others the crossings of the `glass` spheres (zero elsewhere).
#[inline(always)]
pub fn settle_gathered(
    lanes: &RayLanes<Packet>,
    tmax: Packet,
    live: u32,
    opaque: &[(Vec3, f32)],
    glass: &[(Vec3, f32)],
) -> (u32, [u32; PACKET_WIDTH]) {
    let mut blocked = 0;
    for &(center, radius) in opaque {
        let rest = live & !blocked;
        if rest == 0 {
            break;
        }
        blocked |= sphere_lanes(lanes, center, radius, tmax, rest).1;
    }
    let active = live & !blocked;
    let mut counts = [0u32; PACKET_WIDTH];
    for &(center, radius) in glass {
        if active == 0 {
            break;
        }
        let (once, twice) = sphere_crossings(lanes, center, radius, tmax, active);
        for (i, c) in counts.iter_mut().enumerate() {
            *c += (once >> i & 1) + (twice >> i & 1);
        }
    }
    (blocked, counts)
}
