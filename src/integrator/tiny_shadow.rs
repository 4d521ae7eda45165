//! Shadow rays of a tiny scene settled in one pass of lanes ([`TinyShadow`]): the
//! occlusion query and the transmittance through glass spheres in the same lane group,
//! instead of the occlusion batch (`SceneAccel::occluders_batch`, which names the
//! first blocking set of every ray) followed by `ShadowFilter::transmittance_batch`
//! (which copies the rays blocked by the sphere set out and gathers them into lanes a
//! second time).
//!
//! Applies where the scene's batch queries go through [`TinyScene`] and nothing else
//! (no moving geometry, instances or planes), its triangles are all opaque, and its
//! spheres are either all opaque or a split set whose passing part is glass of one
//! transmission (`ShadowFilter::tiny_pass`): the Whitted rows. The answers are the
//! two-step path's bit for bit (a test compares factors and counts on real shadow
//! rays): the same lane kernels run on the same lanes (`TinyGroup::any_triangle`,
//! `any_sphere`, then [`settle_gathered`], the body of `settle_lanes`), each lane's
//! answer depends on its ray alone, and a ray through glass only gets `transmission`
//! multiplied in once per crossing, as `ShadowFilter::glass_factor` does.
//!
//! Measured with the binned lane groups of `accel/tiny.rs` (same change), 1 thread,
//! AVX2, `--stats-json`, interleaved with the previous binary on a machine loaded 5-10
//! on 2 cores (only the ratios mean anything), ms, images byte-identical:
//! whitted_area64 area-shadow stage 15245-17411 -> 10822-11976 (5 runs, load ~9) and
//! 7570-8565 -> 5088-5437 (3 runs, load ~6); whitted_blur16 shadow stage 1023-1123 ->
//! 519-658, whitted_base 71-85 -> 36-46 (3 runs each, load ~3). perf (area64 512x384):
//! the sort by key plus the second gather (`occluders_batch` with `TinyGroup::new`,
//! `transmittance_batch`, `settle_lanes`) were ~21 % of the frame before, the binning
//! and the fused pass ~14 % after.

use super::shadow::ShadowFilter;
use crate::accel::{Occluder, SceneAccel, TINY_MAX_PRIMITIVES, TinyScene, TinyScratch};
use crate::geometry::Ray;
use crate::simd::PACKET_WIDTH;
use crate::simd::Packet;
use crate::simd::direct_light::QuadLight;
use crate::simd::glass_shadow::{SphereRoots, crossings_of_roots, meets_of_roots, settle_gathered};
use crate::simd::kernels::RayLanes;
use crate::simd::kernels::{sphere_roots, sphere_roots_for};
use crate::simd::lanes3::V3;
use crate::simd::quad_samples::{OriginBox, Unpacked3};
use crate::simd::sphere_clearance::{F64_SLACK, clearance, gamma64};
use crate::simd::tiny::{TinyGroup, TrianglePlane, lane_shear_keys};
use crate::stats::RayCounts;
use glam::{DVec3, Vec3};
use std::sync::atomic::{AtomicU64, Ordering};

/// What a shadow ray blocked by the sphere set (and by no triangle) transmits.
#[derive(Clone, Copy)]
pub(super) enum SphereShadow<'a> {
    /// Every sphere blocks light.
    Opaque,
    /// `opaque` spheres block light; `glass` spheres each multiply `transmission` in
    /// once per crossing of their surface.
    Glass {
        opaque: &'a [(Vec3, f32)],
        glass: &'a [(Vec3, f32)],
        transmission: Vec3,
    },
}

/// The one-pass shadow settlement of a tiny scene (see the module).
pub struct TinyShadow<'a> {
    pub(super) tiny: &'a TinyScene,
    pub(super) spheres: SphereShadow<'a>,
}

impl TinyShadow<'_> {
    /// The transmittance of every ray of `rays` into `out`: one where unblocked, zero
    /// where an opaque primitive blocks it, `transmission^n` through `n` glass
    /// crossings; the rays blocked first by a split sphere set are counted in
    /// `counts.transmitted_shadow`. What `occluders_batch` then
    /// `ShadowFilter::transmittance_batch` give, bit for bit.
    pub fn transmittance_batch(
        &self,
        rays: &[Ray],
        out: &mut Vec<Vec3>,
        scratch: &mut TinyScratch,
        counts: &mut RayCounts,
    ) {
        out.clear();
        out.resize(rays.len(), Vec3::ONE);
        let mut settled = 0u64;
        let spheres = self.spheres;
        self.tiny
            .occluder_groups(rays, scratch, |ids, g, tri, sph| {
                for_each_bit(tri, |i| out[ids[i] as usize] = Vec3::ZERO);
                if sph == 0 {
                    return;
                }
                match spheres {
                    SphereShadow::Opaque => {
                        for_each_bit(sph, |i| out[ids[i] as usize] = Vec3::ZERO)
                    }
                    SphereShadow::Glass {
                        opaque,
                        glass,
                        transmission,
                    } => {
                        settled += sph.count_ones() as u64;
                        let (blocked, n) = settle_gathered(&g.lanes, g.tmax, sph, opaque, glass);
                        for_each_bit(sph, |i| {
                            out[ids[i] as usize] = if blocked >> i & 1 == 1 {
                                Vec3::ZERO
                            } else {
                                // `ShadowFilter::glass_factor` with no later sets.
                                let mut t = Vec3::ONE;
                                for _ in 0..n[i] {
                                    t *= transmission;
                                }
                                t
                            };
                        });
                    }
                }
            });
        counts.transmitted_shadow += settled;
    }
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// The shadow settlement of a tiny scene for rays already in lanes: the light samples
/// of one shading point towards one quad light, tested where they are generated
/// (`integrator::area_light`) instead of through the area-shadow queue. An owned copy
/// of the scene's few primitives, so that the shading stage can hold it.
///
/// Applies where the queue path of the area-shadow stage (`wavefront::trace_shadows`)
/// goes through [`TinyShadow`] or through the tiny scene's plain occlusion batch: the
/// scene's batch queries go through its `TinyScene` alone (no moving geometry,
/// instances or planes), and either no shadow ray needs a second query (no
/// [`ShadowFilter`](super::shadow::ShadowFilter)) or the filter has a
/// [`tiny_pass`](super::shadow::ShadowFilter::tiny_pass). Each lane gets the queue
/// path's answer bit for bit: the same lane kernels (`TinyGroup::any_triangle`,
/// `any_sphere`, [`settle_gathered`]) on the same ray fields, grouped by shear key
/// within the sixteen lanes (a lane's answer depends on its ray alone), invalid rays
/// untested and unblocked as `TinyScene::for_each_group` leaves them, and the glass
/// factor multiplied in once per crossing as `transmittance_batch` does.
pub struct LaneOccluders {
    /// Unique per value built (`GroupCull` keys its cache on it).
    id: u64,
    triangles: Vec<[Vec3; 3]>,
    /// Their planes: lanes leaving a triangle's plane from its origin's side skip it.
    planes: Vec<TrianglePlane>,
    /// Per plane, an earlier one that is the same plane (`TrianglePlane::same_plane`:
    /// the two triangles of a quad), whose side and culled lanes it takes.
    twins: Vec<Option<usize>>,
    /// Bit `i` where triangle `i` has no twin (its own plane test).
    untwinned: u32,
    spheres: Vec<(Vec3, f32)>,
    /// Per sphere of the opaque and of the glass list, its index in `spheres` (the
    /// lists are parts of it), so that each sphere is tested once per shading point.
    glass_index: (Vec<Option<usize>>, Vec<Option<usize>>),
    /// Where the sphere set is split: the opaque spheres, the glass spheres and their
    /// transmission (`SphereShadow::Glass`).
    glass: Option<GlassSet>,
    /// `sphere_bits(None)`: every sphere, made once.
    every: SphereBits,
    /// Whether a pack of shading points culls its spheres (`GroupCull`) before the
    /// lane sphere test ([`PACK_SPHERE_CULL`] unless a test sets it).
    pack_sphere_cull: bool,
}

/// Whether a pack of shading points (`area_light::shade_quads_packed`) culls the
/// spheres near its segments ([`GroupCull`], per point) before the lane sphere test:
/// off where a 16-lane value is one register (AVX-512), as the point lights' cull
/// (`point_shadow::SPHERE_CULL`). The answers are the same either way (a culled sphere
/// is one the lane test finds no root on); the tests settle both.
///
/// Why: a pack holds 4 points of 4 samples (dof_area); per point the cull checked its
/// two origins against the group's box (`GroupCull::bits`) and united the bits, and
/// per 16 hits it built a `QuadCull` (f64, then `clear` per sphere): perf, dof_area
/// 960x720, 1 thread, AVX-512, the per-point part ~14 % of `shade_quads_packed`'s
/// samples (~6 % of the frame), `QuadCull::new` and `clear` another ~4 % of the frame,
/// against three sphere tests per pack in one register each (most of them leaving out
/// the square root and two divisions: no lane with a real discriminant,
/// `settle_near_spheres`).
pub const PACK_SPHERE_CULL: bool = !cfg!(target_feature = "avx512f");

/// Per sphere of the glass set's opaque and glass lists, its index in `spheres` (the
/// lists are parts of it), so that each sphere is tested once per group; empty lists
/// without a glass set.
pub(crate) fn glass_index(
    spheres: &[(Vec3, f32)],
    glass: Option<&GlassSet>,
) -> (Vec<Option<usize>>, Vec<Option<usize>>) {
    let index = |list: &[(Vec3, f32)]| {
        list.iter()
            .map(|s| spheres.iter().position(|a| a.0 == s.0 && a.1 == s.1))
            .collect()
    };
    glass.map_or((Vec::new(), Vec::new()), |g| (index(&g.0), index(&g.1)))
}

/// Bit `k` for sphere `k` of `spheres` where `near` holds (the first 32 spheres; a tiny
/// scene has fewer).
pub(crate) fn near_bits(spheres: &[(Vec3, f32)], near: impl Fn(&(Vec3, f32)) -> bool) -> u32 {
    spheres
        .iter()
        .enumerate()
        .fold(0u32, |b, (k, s)| b | (near(s) as u32) << (k & 31))
}

/// Bit `k` for sphere `k` of `list` (a glass set's opaque or glass list) where `near`
/// holds; a listed sphere that is one of the scene's (`index[k] = Some(i)`) takes bit
/// `i` of `all`, the scene's [`near_bits`] for the same `near`, so each sphere is tested
/// once.
pub(crate) fn listed_near_bits(
    list: &[(Vec3, f32)],
    index: &[Option<usize>],
    all: u32,
    near: impl Fn(&(Vec3, f32)) -> bool,
) -> u32 {
    list.iter()
        .zip(index)
        .enumerate()
        .fold(0u32, |b, (k, (s, i))| {
            let n = i.map_or_else(|| near(s), |i| all >> (i & 31) & 1 == 1);
            b | (n as u32) << (k & 31)
        })
}

/// Which spheres a group of segments may meet ([`LaneOccluders::sphere_bits`]): bit
/// `k` for sphere `k` of the scene's list, of the opaque and of the glass list.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereBits {
    all: u32,
    opaque: u32,
    glass: u32,
}

impl SphereBits {
    /// The spheres of either (a pack of shading points' segments: testing a sphere on
    /// a lane it is clear of finds no root there, the cull's answer, so the union
    /// settles every lane as its own bits do).
    pub fn union(self, o: SphereBits) -> SphereBits {
        SphereBits {
            all: self.all | o.all,
            opaque: self.opaque | o.opaque,
            glass: self.glass | o.glass,
        }
    }
}

/// The triangle-plane sides of the shared origin of one shading point's lanes in a
/// pack ([`LaneOccluders::settle_segments`]): the origin last seen and the side of
/// each plane it lies on, as [`NearSpheres`] keeps them for one point.
///
/// Bits per plane (bit `i` for triangle `i`): the origin lies on the side `n` points to
/// (`above`), on the other (`below`), on the plane (`on`); none where the side is not
/// known or not asked for.
///
/// Measured: as an array of `Option<f32>` per plane (`NearSpheres`' form), rewritten
/// per point, its store and reads were ~10 % of `shade_quads_packed`'s samples
/// (dof_area, perf, 1 thread).
#[derive(Clone, Copy, Default)]
pub struct SegmentSides {
    origin: Option<Vec3>,
    above: u32,
    below: u32,
    on: u32,
}

/// Which spheres the light samples of one shading point may meet
/// ([`LaneOccluders::spheres_near`]): bit `k` for sphere `k` of each list.
#[derive(Clone, Copy)]
pub struct NearSpheres {
    all: u32,
    opaque: u32,
    glass: u32,
    /// Bit `k`: triangle `k`'s plane cull may skip some of these segments
    /// (`TrianglePlane::may_cull`); it is not tried for the others.
    planes: u32,
    /// The last shared origin seen and the side of each triangle's plane it lies on
    /// (`TrianglePlane::side`, computed once per shading point and light, not per
    /// lane group).
    sides: (Option<Vec3>, [Option<f32>; TINY_MAX_PRIMITIVES]),
}

impl NearSpheres {
    /// The spheres of `spheres`, with the triangle plane culls `planes` to try and no
    /// plane sides known yet.
    fn new(spheres: SphereBits, planes: u32) -> Self {
        NearSpheres {
            planes,
            sides: (None, [None; TINY_MAX_PRIMITIVES]),
            all: spheres.all,
            opaque: spheres.opaque,
            glass: spheres.glass,
        }
    }
}

/// The quad light's four corners, in order around it.
fn quad_corners(q: &QuadLight) -> [Vec3; 4] {
    [
        q.corner,
        q.corner + q.edge1,
        q.corner + q.edge1 + q.edge2,
        q.corner + q.edge2,
    ]
}

/// Whether the sphere `(center, radius)` is clear of every shadow segment of a shading
/// point towards the quad light `q`, in the sense of `simd::sphere_clearance`: the
/// sphere test finds no root on any of them. `origins` are the segments' two possible
/// origins (`QuadSamples::origins`: each segment starts at one of them, bit for bit).
/// [`QuadCull`] for the box of the two origins (see there for the bound); the lane
/// groups of the renderer use one [`QuadCull`] for the box of all their points'
/// origins ([`GroupCull`]).
///
/// Before (to 2026-11-24): a margin of `1e-4` of the scene's scale, around the
/// shading point's base point; the adversarial test found it wrong for negative radii
/// (the sphere test squares the radius).
pub fn sphere_clear_of(origins: [Vec3; 2], q: &QuadLight, center: Vec3, radius: f32) -> bool {
    OriginBox::of(origins)
        .and_then(|b| QuadCull::new(b.ball(), q))
        .is_some_and(|cull| cull.clear(center, radius))
}

/// Which spheres no shadow segment towards the quad light `q` from an origin within
/// `rho` of `g` can come near ([`clear`](Self::clear)): the part that depends on the
/// origins and the light alone, computed once per lane group of shading points
/// ([`GroupCull`], the ball of an [`OriginBox`]) and light.
///
/// Where the segments lie: each ends at `o + tmax d`, `tmax <= 1`, on `[o, o + d]`;
/// `o + d` misses the offset target by the rounding of `d = fl(target - o)` (at most
/// `u |target - o|`), and the target (`offset_ray_origin` of the light point) lies
/// within `δ = γ8 |A| + (1 + γ32) |q.p_error|` of the exact quad, `A = |corner| +
/// |edge1| + |edge2|` (the light point's three roundings, the offset along the unit
/// normal by `|n|·p_error (1 + γ8)` and its roundings, the one-float step). So every
/// segment point is within `δ + u L` of the convex hull `H` of the ball `B(g, rho)`
/// and the quad's corners (`L` bounds `|target - o|`). A plane through `g` or through
/// the light's corner, unit normal `n` towards the centre, bounds `H` by the largest of
/// `n·(v - p0)` over the corners and `n·(g - p0) + rho` (the ball); the centre's
/// height above that minus `δ + u L` is a lower bound on every segment point's
/// distance from it. Clear where one of these planes gives more than
/// `sphere_clearance::clearance`: the plane across the direction to the centre, the
/// four through `g` and a light edge, the light's own plane. In f64, from the f32
/// inputs; `g` and `rho` carry a few f64 roundings (`OriginBox::ball`), covered with
/// the cull's own by `2^-40` of the magnitudes.
///
/// Measured: computed per sphere and shading point (whitted_area64, 1 thread, 5 runs
/// interleaved with the build before the derived bound, load ~10 on 2 cores, render
/// min/median/max ms) 10833/16239/17727 -> 14812/19553/21191 (a dead end); hoisted
/// per shading point and light 14410/16405/18529 -> 14443/17395/20714, and in a
/// quieter A/B 2067 -> 2600 ms median (perf: `QuadCull::new` and the per-sphere
/// closure 11 %, `clear` 3.4 %); per lane group: see [`GroupCull`].
pub struct QuadCull {
    g: DVec3,
    rho: f64,
    corners: [DVec3; 4],
    /// Per candidate plane (the four through `g` and a light edge, the light's own):
    /// a point on it, its unit normal `n` (zero where degenerate) and the largest
    /// `n·(v - p0)` and `-n·(v - p0)` over the hull's corners and ball.
    planes: [(DVec3, DVec3, f64, f64); 5],
    /// `δ + u L` plus the f64 slack of everything but the centre.
    slack: f64,
    shortest: f64,
    longest: f64,
}

impl QuadCull {
    /// The cull of the segments from origins within `rho` of `g` (`OriginBox::ball`)
    /// to `q`; `None` (nothing clear) for non-finite inputs.
    pub fn new((g, rho): (DVec3, f64), q: &QuadLight) -> Option<QuadCull> {
        const U: f64 = 1.0 / (1u64 << 24) as f64;
        // Non-finite inputs: not clear (the folds below would skip a NaN).
        let finite = [q.corner, q.edge1, q.edge2, q.p_error]
            .iter()
            .all(|v| v.is_finite());
        if !finite || !g.is_finite() || !rho.is_finite() || rho < 0.0 {
            return None;
        }
        let (k, e1, e2) = (q.corner.as_dvec3(), q.edge1.as_dvec3(), q.edge2.as_dvec3());
        let corners = [k, k + e1, k + e1 + e2, k + e2];
        let a = (q.corner.abs() + q.edge1.abs() + q.edge2.abs()).as_dvec3();
        let delta =
            gamma64(8.0) * a.length() + (1.0 + gamma64(32.0)) * q.p_error.as_dvec3().length();
        let reach = corners
            .iter()
            .map(|v| (*v - g).length())
            .fold(0.0f64, f64::max)
            + rho;
        let longest = (reach + delta) * (1.0 + 2.0 * U);
        let mags = [g, k, e1, e2]
            .iter()
            .fold(reach + rho, |m, v| m + v.abs().max_element());
        // Every segment is at least as long as its origin's height above the light's
        // plane.
        let normal = e1.cross(e2).normalize_or_zero();
        let shortest = normal.dot(g - k).abs() - rho - delta;
        let plane = |n: DVec3, p0: DVec3| {
            let n = n.normalize_or_zero();
            let h = n.dot(g - p0);
            let (up, down) = corners.iter().fold((h + rho, rho - h), |(u, d), v| {
                let h = n.dot(*v - p0);
                (u.max(h), d.max(-h))
            });
            (p0, n, up, down)
        };
        let side = |i: usize| plane((corners[i] - g).cross(corners[(i + 1) % 4] - g), g);
        Some(QuadCull {
            g,
            rho,
            corners,
            planes: [side(0), side(1), side(2), side(3), plane(normal, k)],
            slack: delta + U * longest + F64_SLACK * mags,
            shortest: shortest * (1.0 - 2.0 * U),
            longest,
        })
    }

    /// Whether the sphere `(center, radius)` is clear of every segment of the cull's
    /// origins to its light (see the type).
    pub fn clear(&self, center: Vec3, radius: f32) -> bool {
        if !center.is_finite() || !radius.is_finite() {
            return false;
        }
        let c = center.as_dvec3();
        let to = c - self.g;
        let far = to.length() + self.rho;
        let slack = self.slack + F64_SLACK * (c.abs().max_element() + far);
        let Some(need) = clearance(radius, far, slack, self.shortest, self.longest) else {
            return false;
        };
        // The plane across the direction to the centre.
        let axis = to.normalize_or_zero();
        let top = self
            .corners
            .iter()
            .fold(self.rho, |m, v| m.max(axis.dot(*v - self.g)));
        // A zero normal gives `0 - top > need`: false (`top >= rho >= 0`).
        if axis.dot(to) - top > need {
            return true;
        }
        self.planes.iter().any(|&(p0, n, up, down)| {
            let h = n.dot(c - p0);
            // Oriented towards the centre: `n` with its top, or `-n` with its.
            let (h, top) = if h < 0.0 { (-h, down) } else { (h, up) };
            h - top > need
        })
    }
}

/// The spheres near the segments of a lane group of shading points towards each quad
/// light, kept while the renderer walks the group's points ([`bits`](Self::bits)):
/// one [`QuadCull`] per group and light, for the [`OriginBox`] of the group's origins,
/// instead of one per shading point and light. A sphere clear of the box's ball is
/// clear of every segment from any origin in the box, so a point whose two origins
/// the box covers (exact f32 comparisons) may take the group's bits, whichever points
/// built it; a point it does not cover builds the next group, starting at itself.
///
/// Measured (whitted_area64 512x384, counters, since removed): 295,364 shading points,
/// 19,388 groups (15.2 points each); spheres found clear 64.7 % of the tests per group
/// against 70.7 % per point (the box is larger than one point's two origins). A/B at
/// 1024x768 against the per-point cull, interleaved, 5 pairs, load 9-11 on 2 cores,
/// render min/median/max ms: 1 thread 8161/10269/18338 -> 7018/7530/18437 (4 of 5
/// pairs faster), 2 threads 10663/10803/12703 -> 9023/10075/11540 (5 of 5); images
/// byte-identical.
#[derive(Default)]
pub struct GroupCull {
    /// Whose bits these are: the occluders' `id` and the light list's address and
    /// length (the scratch may serve another render's lights).
    owner: (u64, usize, usize),
    cover: Option<OriginBox>,
    /// Per light (in the order given to `bits`), the spheres not clear.
    near: Vec<SphereBits>,
}

impl GroupCull {
    /// The spheres that the segments from `origins` to each light of `lights` may come
    /// near ([`near`](Self::near)`(i)` for light `i`): from the group's box where it
    /// covers `origins`, else from the box `group` makes (the origins of the point and
    /// the ones after it), else every sphere (`false` returned: no cull applies).
    pub fn bits(
        &mut self,
        occluders: &LaneOccluders,
        origins: [Vec3; 2],
        lights: &[(u32, QuadLight)],
        group: impl FnOnce() -> Option<OriginBox>,
    ) -> bool {
        let owner = (occluders.id, lights.as_ptr() as usize, lights.len());
        if self.owner == owner && self.cover.is_some_and(|b| b.covers(origins)) {
            return true;
        }
        self.owner = owner;
        self.cover = group().filter(|b| b.covers(origins));
        self.near.clear();
        let Some(cover) = self.cover else {
            return false;
        };
        let ball = cover.ball();
        self.near.extend(
            lights
                .iter()
                .map(|(_, q)| occluders.sphere_bits(QuadCull::new(ball, q).as_ref())),
        );
        true
    }

    /// The group's bits of light `i` (after [`bits`](Self::bits) returned `true`).
    pub fn near(&self, i: usize) -> SphereBits {
        self.near[i]
    }
}

/// The opaque spheres, the glass spheres and the glass's transmission.
pub(crate) type GlassSet = (Vec<(Vec3, f32)>, Vec<(Vec3, f32)>, Vec3);

/// What [`LaneOccluders::settle`] found for sixteen lanes.
pub struct LaneSettled {
    /// Bits of the lanes whose contribution reaches the shading point: unblocked with a
    /// transmittance that is not zero in every channel (the queue path's
    /// `t != Vec3::ZERO`), invalid rays included (untested).
    pub pass: u32,
    /// The transmittance of each lane (one where no glass is crossed).
    pub factor: V3,
    /// Lanes settled through the glass spheres (`RayCounts::transmitted_shadow`).
    pub settled: u32,
}

/// The tiny scene and its glass split (opaque spheres, glass spheres, transmission;
/// `None`: every sphere opaque) where the queue path (`wavefront::trace_shadows`)
/// settles shadow rays through the tiny scene alone: its batch queries go through the
/// `TinyScene` (no moving geometry, instances or planes), and either no ray needs a
/// second query (no `filter`) or the filter has a `tiny_pass`. What the lane-settled
/// shadows of quad lights ([`LaneOccluders`]) and of point lights
/// (`point_shadow::PointOccluders`) both start from.
pub(crate) fn tiny_shadow_scene<'a>(
    accel: &'a SceneAccel,
    filter: Option<&ShadowFilter>,
) -> Option<(&'a TinyScene, Option<GlassSet>)> {
    let tiny = accel.tiny.as_ref()?;
    if accel.has_sets_from(Occluder::Moving) {
        return None;
    }
    let glass = match filter {
        None => None,
        Some(f) => match f.tiny_pass(accel)?.spheres {
            SphereShadow::Opaque => None,
            SphereShadow::Glass {
                opaque,
                glass,
                transmission,
            } => Some((opaque.to_vec(), glass.to_vec(), transmission)),
        },
    };
    Some((tiny, glass))
}

impl LaneOccluders {
    /// `Some` where the queue path would settle area-shadow rays by the tiny scene
    /// alone (see the type); `filter` is the render's shadow filter.
    pub fn new(accel: &SceneAccel, filter: Option<&ShadowFilter>) -> Option<LaneOccluders> {
        let (tiny, glass) = tiny_shadow_scene(accel, filter)?;
        let planes: Vec<TrianglePlane> = tiny.triangles().iter().map(TrianglePlane::new).collect();
        let twins: Vec<Option<usize>> = (0..planes.len())
            .map(|i| (0..i).find(|&j| planes[j].same_plane(&planes[i])))
            .collect();
        let untwinned = twins
            .iter()
            .enumerate()
            .fold(0u32, |b, (i, t)| b | (t.is_none() as u32) << (i & 31));
        let spheres = tiny.spheres().to_vec();
        let glass_index = glass_index(&spheres, glass.as_ref());
        static NEXT: AtomicU64 = AtomicU64::new(1);
        let mut occluders = LaneOccluders {
            id: NEXT.fetch_add(1, Ordering::Relaxed),
            triangles: tiny.triangles().to_vec(),
            planes,
            twins,
            untwinned,
            spheres,
            glass_index,
            glass,
            every: SphereBits {
                all: 0,
                opaque: 0,
                glass: 0,
            },
            pack_sphere_cull: PACK_SPHERE_CULL,
        };
        occluders.every = occluders.sphere_bits(None);
        Some(occluders)
    }

    /// The same occluders with a pack's sphere cull on or off (the answers are the
    /// same either way; the tests settle both).
    #[cfg(test)]
    pub fn with_pack_sphere_cull(mut self, on: bool) -> LaneOccluders {
        self.pack_sphere_cull = on;
        self
    }

    /// Whether a pack of shading points culls its spheres ([`PACK_SPHERE_CULL`]).
    pub fn pack_sphere_cull(&self) -> bool {
        self.pack_sphere_cull
    }

    /// Every sphere: `sphere_bits(None)`, made once.
    pub fn every_sphere(&self) -> SphereBits {
        self.every
    }

    /// The spheres not clear of the segments `cull` covers (every sphere where
    /// `cull` is `None`): one bit per sphere of the scene's list, of the opaque and of
    /// the glass list.
    pub fn sphere_bits(&self, cull: Option<&QuadCull>) -> SphereBits {
        let near = |&(c, r): &(Vec3, f32)| !cull.is_some_and(|cull| cull.clear(c, r));
        let all = near_bits(&self.spheres, near);
        // A listed sphere that is one of `spheres` takes its bit (the same call).
        let bits = |list: &[(Vec3, f32)], index: &[Option<usize>]| {
            listed_near_bits(list, index, all, near)
        };
        let (oi, gi) = &self.glass_index;
        SphereBits {
            all,
            opaque: self.glass.as_ref().map_or(0, |g| bits(&g.0, oi)),
            glass: self.glass.as_ref().map_or(0, |g| bits(&g.1, gi)),
        }
    }

    /// What [`settle`](Self::settle) tests for the light samples of one shading point
    /// (base point `base`, which decides which triangle planes are tried) towards the
    /// quad light `q`: the spheres of `spheres` (`sphere_bits` of a cull covering the
    /// point's segments).
    pub fn spheres_near(&self, base: Vec3, spheres: SphereBits, q: &QuadLight) -> NearSpheres {
        let corners = quad_corners(q);
        let planes = self.planes.iter().enumerate().fold(0u32, |b, (k, p)| {
            b | (p.may_cull(base, &corners) as u32) << (k & 31)
        });
        NearSpheres::new(spheres, planes)
    }

    /// [`spheres_near`](Self::spheres_near) for the light samples of several shading
    /// points in one lane group (base points `bases`, the lanes of `live`): a
    /// triangle's plane cull is tried where it may skip some segment of any of them (it
    /// is exact wherever it is applied: `TrianglePlane::leaving`), asked for every
    /// point at once (`TrianglePlane::may_cull_lanes`).
    pub fn spheres_near_points(
        &self,
        bases: V3,
        live: u32,
        spheres: SphereBits,
        q: &QuadLight,
    ) -> NearSpheres {
        let corners = quad_corners(q);
        // Only the planes `settle_segments` reads (a twin takes its plane's sides).
        let mut planes = 0u32;
        let mut ask = if live == 0 { 0 } else { self.untwinned };
        while ask != 0 {
            let k = ask.trailing_zeros() as usize;
            ask &= ask - 1;
            if self
                .planes
                .get(k)
                .is_some_and(|p| p.may_cull_lanes(bases, &corners) & live != 0)
            {
                planes |= 1 << k;
            }
        }
        NearSpheres::new(spheres, planes)
    }

    /// [`settle`](Self::settle) for lanes holding the light samples of several shading
    /// points (a pack: `segments[j].0` the lanes of point `j`, `segments[j].1` the
    /// plane sides of its shared origin, kept across calls): every lane gets the answer
    /// `settle` gives it. Per point whose valid lanes share one origin, the plane cull
    /// from that origin's sides (computed once per origin, as `settle` does per point);
    /// per key group, the triangle test from the lanes' origins; the spheres of
    /// `near_spheres` (the union of the points' bits) once for every valid lane.
    #[inline(always)]
    pub fn settle_segments(
        &self,
        origin: V3,
        dir: V3,
        tmax: Packet,
        live: u32,
        near_spheres: &NearSpheres,
        segments: &mut [(u32, SegmentSides)],
    ) -> LaneSettled {
        let (lanes, keys, valid) = key_lanes(origin, dir, tmax, live);
        // Per plane, the lanes leaving it away from their point's shared origin, and
        // its two directions of leaving (computed on first need).
        let mut culled = [0u32; TINY_MAX_PRIMITIVES];
        let mut away: [Option<(u32, u32)>; TINY_MAX_PRIMITIVES] = [None; TINY_MAX_PRIMITIVES];
        // The origins' lanes unpacked once for the points (`V3::lane` per point stored
        // the three coordinates' lanes each time: ~5 % of `shade_quads_packed`'s perf
        // samples, dof_area 960x720, 1 thread).
        let unpacked = Unpacked3::of(origin);
        for (seg, cache) in segments.iter_mut() {
            let v = valid & *seg;
            if v == 0 {
                continue;
            }
            let Some(o) = shared_origin_of(origin, &unpacked, v) else {
                continue;
            };
            if cache.origin != Some(o) {
                // The sides of the planes tried (a twin takes its plane's lanes below).
                let (mut above, mut below, mut on) = (0, 0, 0);
                let mut tried = near_spheres.planes & self.untwinned;
                while tried != 0 {
                    let i = tried.trailing_zeros() as usize;
                    tried &= tried - 1;
                    match self.planes.get(i).and_then(|p| p.side(o)) {
                        Some(side) if side > 0.0 => above |= 1 << i,
                        Some(side) if side < 0.0 => below |= 1 << i,
                        Some(_) => on |= 1 << i,
                        None => {}
                    }
                }
                *cache = SegmentSides {
                    origin: Some(o),
                    above,
                    below,
                    on,
                };
            }
            let mut known = cache.above | cache.below | cache.on;
            while known != 0 {
                let i = known.trailing_zeros() as usize & (TINY_MAX_PRIMITIVES - 1);
                known &= known - 1;
                let (up, down) =
                    *away[i].get_or_insert_with(|| self.planes[i].away(&lanes.d, valid));
                let bit = 1 << i;
                culled[i] |= v & if cache.above & bit != 0 {
                    up
                } else if cache.below & bit != 0 {
                    down
                } else {
                    up | down
                };
            }
        }
        let mut reach = [valid; TINY_MAX_PRIMITIVES];
        for (i, twin) in self.twins.iter().enumerate().take(TINY_MAX_PRIMITIVES) {
            reach[i] = match *twin {
                Some(j) if j < i => reach[j],
                _ => valid & !culled[i],
            };
        }
        let tri = self.triangle_blocks(&keys, live, &lanes, tmax, &reach);
        self.settle_spheres(&lanes, tmax, (live, tri, valid & !tri), near_spheres)
    }

    /// Settles the rays `origin + t dir`, `t` in `(0, tmax)`, of the lanes in `live`,
    /// testing only the spheres in `near_spheres` (the others meet none of these
    /// rays); it keeps the triangle sides of the last shared origin.
    #[inline(always)]
    pub fn settle(
        &self,
        origin: V3,
        dir: V3,
        tmax: Packet,
        live: u32,
        near_spheres: &mut NearSpheres,
    ) -> LaneSettled {
        let (lanes, keys, valid) = key_lanes(origin, dir, tmax, live);
        // One origin for every valid lane (the common case: every sample of a shading
        // point leaves from the same offset point).
        let shared = shared_origin(origin, valid);
        // Per triangle, the valid lanes that may meet it: all but those leaving its
        // plane from the shared origin's side (`TrianglePlane`), tried where it may
        // skip some (`NearSpheres::planes`); below, per key group, also all but those
        // ending before its corners (`TinyGroup::beyond`: the light's own triangles).
        //
        // Measured before `beyond` (counters, whitted_area64 512x384): every lane group
        // ran the full triangle test on both of the light's triangles (each sample's
        // segment ends just short of them), the largest part of `shade_quads`.
        let mut reach = [valid; TINY_MAX_PRIMITIVES];
        if let Some(o) = shared {
            if near_spheres.sides.0 != Some(o) {
                let mut sides = [None; TINY_MAX_PRIMITIVES];
                for (i, (plane, twin)) in self.planes.iter().zip(&self.twins).enumerate() {
                    let tried = near_spheres.planes >> (i & 31) & 1 == 1;
                    sides[i] = match *twin {
                        Some(j) => sides[j],
                        None if tried => plane.side(o),
                        None => None,
                    };
                }
                near_spheres.sides = (Some(o), sides);
            }
            let sides = &near_spheres.sides.1;
            for (i, (plane, twin)) in self.planes.iter().zip(&self.twins).enumerate() {
                match (*twin, sides[i]) {
                    (Some(j), _) => reach[i] = reach[j],
                    (None, Some(side)) => reach[i] &= !plane.leaving(side, &lanes.d, valid),
                    (None, None) => {}
                }
            }
        }
        let tri = self.triangle_blocks(&keys, live, &lanes, tmax, &reach);
        self.settle_spheres(&lanes, tmax, (live, tri, valid & !tri), near_spheres)
    }

    /// The lanes of `live` that a triangle blocks, one shear-key group at a time
    /// (`keys`), each lane tested only against the triangles in its `reach` (the
    /// lanes' own origins: the packet triangle test translates the corners by each
    /// lane's origin in one instruction per coordinate, shared origin or not).
    /// The light's own triangles, beyond the segments' ends, are skipped by
    /// `TinyGroup::beyond` before the full test.
    #[inline(always)]
    fn triangle_blocks(
        &self,
        keys: &[u32; 6],
        live: u32,
        lanes: &RayLanes<Packet>,
        tmax: Packet,
        reach: &[u32; TINY_MAX_PRIMITIVES],
    ) -> u32 {
        let mut tri = 0u32;
        for (key, &bits) in keys.iter().enumerate() {
            let mask = bits & live;
            if mask == 0 {
                continue;
            }
            let g = TinyGroup::from_lanes(key, *lanes, tmax, mask);
            let mut t = 0;
            for (corners, &reach) in self.triangles.iter().zip(reach) {
                let test = mask & reach & !t;
                if test != 0 {
                    let test = test & !g.beyond(corners, test);
                    if test != 0 {
                        t |= g.triangle_blocks(corners, test);
                    }
                }
            }
            tri |= t;
        }
        tri
    }

    /// The spheres once for all valid lanes of `(live, tri, open)`, not once per key
    /// group: a sphere's lane test reads the lanes as they are (`TinyGroup` holds
    /// `lanes` unchanged), so each lane is tested against the same spheres with the
    /// same answers as per group. Each near sphere's roots are kept for the glass
    /// settlement.
    ///
    /// Measured (whitted_area64 512x384, 1 thread, AVX-512, perf): before, the sphere
    /// test per key group was 7.1 % of the frame's samples, and the glass settlement
    /// (`settle_gathered`, computing the same roots again) 4.5 %.
    #[inline(always)]
    fn settle_spheres(
        &self,
        lanes: &RayLanes<Packet>,
        tmax: Packet,
        lanes_of: (u32, u32, u32),
        near_spheres: &NearSpheres,
    ) -> LaneSettled {
        settle_near_spheres(
            lanes,
            tmax,
            lanes_of,
            &self.spheres,
            near_spheres.all,
            self.glass.as_ref(),
            &self.glass_index,
            |_| (near_spheres.opaque, near_spheres.glass),
        )
    }
}

/// The lanes of the rays `origin + t dir`, `t` in `(0, tmax)`, their shear-key groups,
/// and the lanes of `live` that some group takes (the valid ones).
#[inline(always)]
fn key_lanes(origin: V3, dir: V3, tmax: Packet, live: u32) -> (RayLanes<Packet>, [u32; 6], u32) {
    let lanes = RayLanes {
        o: [origin.x, origin.y, origin.z],
        d: [dir.x, dir.y, dir.z],
        tmin: Packet::splat(0.0),
    };
    let keys = lane_shear_keys(&lanes, tmax);
    let valid = keys.iter().fold(0, |a, &k| a | k) & live;
    (lanes, keys, valid)
}

/// The origin that every lane of `lanes` holds, where they hold one bit for bit: equal
/// as floats and with equal sign bits (`to_bitmask` reads the sign bits), so a zero and
/// a negative zero differ; `None` for no lanes or different origins.
#[inline(always)]
fn shared_origin(origin: V3, lanes: u32) -> Option<Vec3> {
    shared_origin_of(origin, &Unpacked3::of(origin), lanes)
}

/// [`shared_origin`] with `origin`'s lanes unpacked (`unpacked`).
#[inline(always)]
fn shared_origin_of(origin: V3, unpacked: &Unpacked3, lanes: u32) -> Option<Vec3> {
    if lanes == 0 {
        return None;
    }
    let o = unpacked.lane(lanes.trailing_zeros() as usize);
    let same = |p: Packet, v: f32| {
        let signs = p.to_bitmask();
        let signs = if v.is_sign_negative() { signs } else { !signs };
        p.simd_eq(Packet::splat(v)).to_bitmask() & signs & lanes
    };
    (same(origin.x, o.x) & same(origin.y, o.y) & same(origin.z, o.z) == lanes).then_some(o)
}

/// The spheres of both lane-settled shadow paths (quad lights in [`LaneOccluders`],
/// point lights in `point_shadow`): of the `live` lanes, `tri` are blocked by a
/// triangle and `open` (valid, not blocked by a triangle) are tested against the
/// spheres of `spheres` whose bit is set in `all` (the others meet none of these
/// rays), each sphere's roots computed once (`sphere_roots`) and kept for the glass
/// settlement. Without a glass split every sphere blocks; with one (`glass`, its lists'
/// indices in `spheres` in `index`), the sphere lanes are settled as the queue path
/// settles them (`settle_gathered(lanes, tmax, sph, opaque, glass)` on the spheres
/// `near_lists` picks from each list: its bits of the opaque and the glass list), each
/// lane's transmittance multiplied in once per crossing, and a lane passes unless
/// blocked or fully dark.
///
/// The roots of a sphere do not depend on the lanes asked about (`meets_of_roots` and
/// `crossings_of_roots` are `sphere_lanes` and `sphere_crossings` on them), so every
/// answer is the one `settle_gathered` gives.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn settle_near_spheres(
    lanes: &RayLanes<Packet>,
    tmax: Packet,
    (live, tri, open): (u32, u32, u32),
    spheres: &[(Vec3, f32)],
    all: u32,
    glass: Option<&GlassSet>,
    index: &(Vec<Option<usize>>, Vec<Option<usize>>),
    near_lists: impl FnOnce(&GlassSet) -> (u32, u32),
) -> LaneSettled {
    let mut roots: [Option<SphereRoots<Packet>>; TINY_MAX_PRIMITIVES] = [None; TINY_MAX_PRIMITIVES];
    let mut sph = 0u32;
    // A sphere whose line misses every lane that can still read its roots (no real
    // discriminant there) keeps zeros and no bits without its square root and two
    // divisions (`sphere_roots_for`): the same answers. With a glass set, the glass
    // settlement below reads the kept roots on lanes of `open` (`rest`, `sph` and its
    // lanes are parts of it), so the skip asks `open`; without one every sphere blocks,
    // no roots are kept, and it asks only `rest` (the bits `sphere_lanes` gives). Most
    // shadow rays of a lane group pass a sphere by together (floor points outside its
    // shadow).
    //
    // Measured (helper bl22, 2026-11-29, 1 thread, host load 3-9, images
    // byte-identical): `shade_group_lanes`' share of the perf samples (cpu-clock),
    // whitted_blur16, 5 interleaved pairs, 33.6-36.1 % -> 32.6-34.2 % (lower in every
    // pair), aa3x3 35.0-36.5 % -> 34.0-34.7 %; render phase, 7 interleaved rounds,
    // min/median/max ms, whitted_blur16 1894/2147/2510 -> 1838/2004/2426.
    for (k, &(center, radius)) in spheres.iter().enumerate() {
        let rest = open & !sph;
        if all >> (k & 31) & 1 == 1 && rest != 0 {
            let reads = if glass.is_some() { open } else { rest };
            let r = sphere_roots_for(lanes, center, radius, reads);
            sph |= meets_of_roots(lanes, r, tmax, rest);
            if glass.is_some()
                && let Some(slot) = roots.get_mut(k)
            {
                *slot = Some(r);
            }
        }
    }
    let Some(set) = glass else {
        return LaneSettled {
            pass: live & !(tri | sph),
            factor: V3::splat(Vec3::ONE),
            settled: 0,
        };
    };
    if sph == 0 {
        return LaneSettled {
            pass: live & !tri,
            factor: V3::splat(Vec3::ONE),
            settled: 0,
        };
    }
    let (opaque, glass, transmission) = set;
    let (opaque_bits, glass_bits) = near_lists(set);
    // `settle_gathered(lanes, tmax, sph, opaque, glass)` on the near spheres of each
    // list, each sphere's roots taken from above where its test ran there.
    let (oi, gi) = index;
    let mut roots_of = |s: &(Vec3, f32), index: Option<usize>| match index {
        Some(i) if i < TINY_MAX_PRIMITIVES => {
            *roots[i].get_or_insert_with(|| sphere_roots(lanes, s.0, s.1))
        }
        // (Every listed sphere is one of the scene's: `glass_index`.)
        _ => sphere_roots(lanes, s.0, s.1),
    };
    let mut blocked = 0;
    for (k, (s, &index)) in opaque.iter().zip(oi).enumerate() {
        let rest = sph & !blocked;
        if rest == 0 {
            break;
        }
        if opaque_bits >> (k & 31) & 1 == 1 {
            blocked |= meets_of_roots(lanes, roots_of(s, index), tmax, rest);
        }
    }
    let active = sph & !blocked;
    let mut n = [0u32; PACKET_WIDTH];
    for (k, (s, &index)) in glass.iter().zip(gi).enumerate() {
        if active == 0 {
            break;
        }
        if glass_bits >> (k & 31) & 1 == 1 {
            let (once, twice) = crossings_of_roots(lanes, roots_of(s, index), tmax, active);
            for (i, c) in n.iter_mut().enumerate() {
                *c += (once >> i & 1) + (twice >> i & 1);
            }
        }
    }
    glass_settled((live, tri, sph), blocked, &n, *transmission)
}

/// The end of [`settle_near_spheres`] with a glass split: of the `live` lanes, `tri` are
/// blocked by a triangle, `sph` meet a sphere, `blocked` of those an opaque one, and
/// the others cross the glass spheres `n[i]` times.
#[inline(always)]
fn glass_settled(
    (live, tri, sph): (u32, u32, u32),
    blocked: u32,
    n: &[u32; PACKET_WIDTH],
    transmission: Vec3,
) -> LaneSettled {
    let one = V3::splat(Vec3::ONE);
    // `t *= transmission` once per crossing, lane by lane: the same products in the
    // same order as the scalar loop (`ShadowFilter::glass_factor`).
    let counts = Packet::new(n.map(|c| c as f32));
    let most = n.iter().max().copied().unwrap_or(0);
    let tr = V3::splat(transmission);
    let mut factor = one;
    for k in 0..most {
        let more = counts.simd_gt(Packet::splat(k as f32));
        factor = V3::select(more, factor.times(tr), factor);
    }
    let zero = Packet::splat(0.0);
    let dark = factor.x.simd_eq(zero) & factor.y.simd_eq(zero) & factor.z.simd_eq(zero);
    LaneSettled {
        pass: live & !tri & !blocked & !dark.to_bitmask(),
        factor,
        settled: sph,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{RayQuery, intersect_sphere};
    use crate::test_rng::xorshift64;

    /// Where [`sphere_clear_of`] says a sphere is clear of a shading point's light
    /// samples, the scalar sphere test ([`intersect_sphere`], which the lane test
    /// repeats bit for bit) finds no root on any shadow segment from the point to the
    /// light: random spheres, quad lights and points, 64 segments each to random light
    /// points built as the renderer builds them (`quad_light`'s `spawn_ray_to`).
    #[test]
    fn spheres_clear_of_a_light_meet_none_of_its_segments() {
        let mut next = xorshift64(0x2545_f491_4f6c_dd1d);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut clear, mut cases) = (0, 0);
        for _ in 0..3000 {
            let mut r3 = |s: f32| Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s;
            let q = QuadLight::new(
                Vec3::new(-2.0, 5.0, -1.0) + r3(4.0),
                Vec3::new(2.0, 0.0, 0.0) + r3(1.0),
                Vec3::new(0.0, 0.0, 2.0) + r3(1.0),
                Vec3::ONE,
            );
            let center = r3(6.0) + Vec3::new(0.0, 1.5, 0.0);
            let radius = 0.2 + unit() * 1.2;
            let p = Vec3::new(unit() - 0.5, 0.0, unit() - 0.5) * 16.0;
            cases += 1;
            let p_error = Vec3::splat(1e-6);
            let origins = [Vec3::Y, -Vec3::Y]
                .map(|w| crate::geometry::offset_ray_origin(p, p_error, Vec3::Y, w));
            if !sphere_clear_of(origins, &q, center, radius) {
                continue;
            }
            clear += 1;
            for _ in 0..64 {
                let point = q.corner + q.edge1 * unit() + q.edge2 * unit();
                let ray =
                    crate::geometry::spawn_ray_to(p, p_error, Vec3::Y, point, q.p_error, q.normal);
                let query = RayQuery::new(&ray).expect("a valid segment");
                assert!(
                    intersect_sphere(&query, center, radius, ray.tmax).is_none(),
                    "{ray:?} meets the sphere {center} {radius} said clear"
                );
            }
        }
        eprintln!("{clear} of {cases} spheres clear of the light");
        assert!(clear > 500 && clear < cases);
    }

    /// Adversarial cases for [`sphere_clear_of`]: wherever it says clear, neither the
    /// scalar sphere test nor its lane twin finds a root on any light sample's shadow
    /// ray, built as the renderer builds them (`QuadSamples::lanes`, both origins):
    /// scenes of scale 1e-3, 1 and 1e4, shifted to 1e5 from the origin or not, tiny
    /// spheres (1e-7 and 1e-3 of the scale) and large ones, spheres placed tangent to
    /// the segment towards a corner, an edge point or a random light point, pushed out
    /// by 1e-1 down to 1e-9 of its length and slid along it past both ends, a few ulps
    /// of tangency, thin and degenerate quads, negative radii; the samples include the
    /// quad's corners and edge midpoints. Non-finite inputs are never clear.
    #[test]
    fn sphere_clear_of_holds_against_adversarial_spheres() {
        use crate::simd::direct_light::{Highlight, SurfaceLanes};
        use crate::simd::quad_samples::QuadSamples;
        fn r3(unit: &mut impl FnMut() -> f32, s: f32) -> Vec3 {
            Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
        }
        let mut next = xorshift64(0x6a09_e667_f3bc_c908);
        let (mut cases, mut clear, mut close, mut rays) = (0usize, 0usize, 0usize, 0usize);
        let hl = Highlight {
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        for case in 0..24_000 {
            let mut unit = || (next() >> 40) as f32 / (1u64 << 24) as f32;
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let shift = if case % 6 < 3 {
                Vec3::ZERO
            } else {
                Vec3::new(1e5, -3e4, 7e4) * scale
            };
            let corner = shift + (r3(&mut unit, 8.0) + Vec3::Y * 5.0) * scale;
            let edge1 = r3(&mut unit, 4.0) * scale;
            let edge2 = match case % 11 {
                0 => Vec3::ZERO,
                1 => edge1 * 0.5,
                2 => edge1.cross(Vec3::Y).normalize_or_zero() * 1e-6 * scale,
                _ => r3(&mut unit, 4.0) * scale,
            };
            let q = QuadLight::new(corner, edge1, edge2, Vec3::ONE);
            let p = shift + r3(&mut unit, 16.0) * scale;
            let ng = r3(&mut unit, 2.0).normalize_or(Vec3::Y);
            let p_error = crate::geometry::gamma(5) * p.abs() + r3(&mut unit, 1e-6).abs() * scale;
            let s = SurfaceLanes::splat_point(p, p_error, ng, Vec3::ONE);
            let fast = QuadSamples::new(&s, &hl).expect("a unit normal");
            // The light points: corners, edge midpoints, then random ones.
            let fixed = [
                (0.0, 0.0),
                (1.0, 0.0),
                (0.0, 1.0),
                (1.0, 1.0),
                (0.5, 0.0),
                (0.0, 0.5),
                (1.0, 0.5),
                (0.5, 1.0),
            ];
            let mut uv: Vec<(f32, f32)> = fixed.to_vec();
            uv.extend((0..56).map(|_| (unit(), unit())));
            // The sphere: tangent to one segment, or anywhere.
            let (pu, pv) = uv[(unit() * uv.len() as f32) as usize % uv.len()];
            let target = q.corner + q.edge1 * pu + q.edge2 * pv;
            let radius = [1e-7f32, 1e-3, 0.05, 0.8][case / 4 % 4] * scale;
            let push = 10f32.powf(-1.0 - 8.0 * unit());
            let center = match case % 4 {
                3 => shift + (r3(&mut unit, 12.0) + Vec3::Y * 2.0) * scale,
                k => {
                    let along = [-0.05, 0.0, unit(), 1.0, 1.05][(case / 16 + k) % 5];
                    let seg = target - p;
                    let side = seg.cross(r3(&mut unit, 1.0)).normalize_or(Vec3::X);
                    let out = if case % 13 == 0 {
                        // A few ulps of the distance from tangency.
                        radius * (1.0 + (case / 13 % 8) as f32 * f32::EPSILON)
                    } else {
                        radius + push * seg.length()
                    };
                    p + seg * along + side * out
                }
            };
            let radius = if case % 17 == 0 { -radius } else { radius };
            cases += 1;
            if !sphere_clear_of(fast.origins(), &q, center, radius) {
                continue;
            }
            clear += 1;
            close += (case % 4 != 3 && push < 1e-4) as usize;
            for c in (0..uv.len()).step_by(16) {
                let u = Packet::new(std::array::from_fn(|i| uv[c + i].0));
                let v = Packet::new(std::array::from_fn(|i| uv[c + i].1));
                let sl = fast.lanes(&s, &hl, &q, u, v, 64.0, 0xffff);
                rays += 16;
                if let Some(ray) = crate::simd::shadow_cull::lanes_meeting(&sl, center, radius) {
                    panic!(
                        "case {case}: {ray:?} meets the sphere {center} {radius} said clear \
                         of {q:?} from {p}"
                    );
                }
            }
        }
        // Non-finite inputs.
        let q = QuadLight::new(Vec3::Y * 4.0, Vec3::X, Vec3::Z, Vec3::ONE);
        for bad in [f32::NAN, f32::INFINITY, -f32::INFINITY] {
            let far = Vec3::new(0.0, -50.0, 0.0);
            let o = [Vec3::ZERO, Vec3::ZERO];
            assert!(!sphere_clear_of(o, &q, far, bad));
            assert!(!sphere_clear_of(o, &q, Vec3::new(bad, -50.0, 0.0), 1.0));
            assert!(!sphere_clear_of(
                [Vec3::new(0.0, bad, 0.0); 2],
                &q,
                far,
                1.0
            ));
            let nq = QuadLight::new(Vec3::new(bad, 4.0, 0.0), Vec3::X, Vec3::Z, Vec3::ONE);
            assert!(!sphere_clear_of(o, &nq, far, 1.0));
        }
        eprintln!("{clear} of {cases} spheres clear ({close} pushed out by < 1e-4), {rays} rays");
        assert!(
            clear > cases / 4 && close > 500,
            "{clear} clear, {close} close"
        );
    }

    /// Adversarial cases for the lane-group entry of the cull, as `shade_quads` uses
    /// it: [`OriginBox::of_group`] over sixteen shading points, its ball, one
    /// [`QuadCull`]. Wherever it says a sphere is clear, neither the scalar sphere test
    /// nor its lane twin finds a root on any shadow ray of any member the box covers
    /// (each member's own `QuadSamples::lanes`, both origins: the eight corners and edge
    /// midpoints of the light, the point the sphere was placed against and seven
    /// random points). Groups: clustered points, points spread over the whole scene
    /// (far apart), one point sixteen times (a degenerate box), points on a line, a
    /// cluster with one outlier, partial groups; lanes with a zero or NaN normal, a NaN
    /// or infinite position (left out of the box and not covered); scales 1e-3, 1 and
    /// 1e4, shifted far from the origin or not, the quads and spheres of
    /// `sphere_clear_of_holds_against_adversarial_spheres` (tangent to one member's
    /// segment, pushed out by 1e-1 down to 1e-9 of its length, a few ulps, negative
    /// radii, thin and degenerate quads). Every member with a finite positive-length
    /// normal and finite origins is covered by its group's box.
    #[test]
    fn group_cull_holds_against_adversarial_spheres() {
        use crate::simd::direct_light::{Highlight, SurfaceLanes};
        use crate::simd::quad_samples::QuadSamples;
        fn r3(unit: &mut impl FnMut() -> f32, s: f32) -> Vec3 {
            Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
        }
        let mut next = xorshift64(0xbb67_ae85_84ca_a73b);
        let (mut cases, mut clear, mut close, mut rays, mut spread_clear) = (0, 0, 0, 0, 0);
        let mut members = 0usize;
        let hl = Highlight {
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        let fixed = [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (1.0, 1.0),
            (0.5, 0.0),
            (0.0, 0.5),
            (1.0, 0.5),
            (0.5, 1.0),
        ];
        for case in 0..6000 {
            let mut unit = || (next() >> 40) as f32 / (1u64 << 24) as f32;
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let shift = if case % 6 < 3 {
                Vec3::ZERO
            } else {
                Vec3::new(1e5, -3e4, 7e4) * scale
            };
            let corner = shift + (r3(&mut unit, 8.0) + Vec3::Y * 5.0) * scale;
            let edge1 = r3(&mut unit, 4.0) * scale;
            let edge2 = match case % 11 {
                0 => Vec3::ZERO,
                1 => edge1 * 0.5,
                2 => edge1.cross(Vec3::Y).normalize_or_zero() * 1e-6 * scale,
                _ => r3(&mut unit, 4.0) * scale,
            };
            let q = QuadLight::new(corner, edge1, edge2, Vec3::ONE);
            // The group's points.
            let kind = case / 3 % 5;
            let p0 = shift + r3(&mut unit, 16.0) * scale;
            let dir = r3(&mut unit, 2.0).normalize_or(Vec3::X);
            let mut ps: [Vec3; 16] = std::array::from_fn(|i| match kind {
                0 => p0 + r3(&mut unit, 1e-2) * scale,
                1 => shift + r3(&mut unit, 16.0) * scale,
                2 => p0,
                3 => p0 + dir * (i as f32 * 0.3 * scale),
                _ if i == 7 => p0 + r3(&mut unit, 30.0) * scale,
                _ => p0 + r3(&mut unit, 1e-2) * scale,
            });
            let mut ng: [Vec3; 16] =
                std::array::from_fn(|_| r3(&mut unit, 2.0).normalize_or(Vec3::Y));
            if case % 7 == 0 {
                ng[3] = Vec3::ZERO;
                ng[5] = Vec3::NAN;
                ps[9] = Vec3::new(f32::NAN, 0.0, 0.0);
                ps[11] = Vec3::new(0.0, f32::INFINITY, 0.0);
            }
            let p_error: [Vec3; 16] = std::array::from_fn(|i| {
                crate::geometry::gamma(5) * ps[i].abs() + r3(&mut unit, 1e-6).abs() * scale
            });
            let n = if case % 4 == 1 { 1 + case / 4 % 16 } else { 16 };
            let live = (1u32 << n) - 1;
            let lanes = |v: &[Vec3; 16]| V3 {
                x: Packet::new(v.map(|v| v.x)),
                y: Packet::new(v.map(|v| v.y)),
                z: Packet::new(v.map(|v| v.z)),
            };
            let group = OriginBox::of_group(lanes(&ps), lanes(&p_error), lanes(&ng), live);
            // Each member's own samples and whether the box covers it.
            let surface = |i: usize| SurfaceLanes {
                p: V3::splat(ps[i]),
                p_error: V3::splat(p_error[i]),
                ng: V3::splat(ng[i]),
                ns: V3::splat(ng[i]),
                base: V3::splat(ps[i]),
                smooth: Packet::splat(0.0),
                wo: V3::splat(ng[i]),
                albedo: V3::splat(Vec3::ONE),
            };
            let mut covered = Vec::new();
            for i in 0..n {
                let s = surface(i);
                let Some(fast) = QuadSamples::new(&s, &hl) else {
                    continue;
                };
                let o = fast.origins();
                let inside = group.is_some_and(|b| b.covers(o));
                if o[0].is_finite() && o[1].is_finite() {
                    assert!(inside, "case {case}: member {i} {o:?} outside {group:?}");
                    covered.push((s, fast));
                } else {
                    assert!(!inside, "case {case}: non-finite member {i} covered");
                }
            }
            members += covered.len();
            let Some(b) = group else {
                assert!(covered.is_empty(), "case {case}: members but no box");
                continue;
            };
            // The sphere: tangent to one member's segment, or anywhere.
            let m = (unit() * covered.len() as f32) as usize % covered.len();
            let p = covered[m].0.base.lane(0);
            let (pu, pv) = if unit() < 0.3 {
                fixed[(unit() * 8.0) as usize % 8]
            } else {
                (unit(), unit())
            };
            let target = q.corner + q.edge1 * pu + q.edge2 * pv;
            let radius = [1e-7f32, 1e-3, 0.05, 0.8][case / 4 % 4] * scale;
            let push = 10f32.powf(-1.0 - 8.0 * unit());
            let center = match case % 4 {
                3 => shift + (r3(&mut unit, 12.0) + Vec3::Y * 2.0) * scale,
                k => {
                    let along = [-0.05, 0.0, unit(), 1.0, 1.05][(case / 16 + k) % 5];
                    let seg = target - p;
                    let side = seg.cross(r3(&mut unit, 1.0)).normalize_or(Vec3::X);
                    let out = if case % 13 == 0 {
                        radius * (1.0 + (case / 13 % 8) as f32 * f32::EPSILON)
                    } else {
                        radius + push * seg.length()
                    };
                    p + seg * along + side * out
                }
            };
            let radius = if case % 17 == 0 { -radius } else { radius };
            cases += 1;
            if !QuadCull::new(b.ball(), &q).is_some_and(|c| c.clear(center, radius)) {
                continue;
            }
            clear += 1;
            spread_clear += (kind == 1) as usize;
            close += (case % 4 != 3 && push < 1e-4) as usize;
            let mut uv: Vec<(f32, f32)> = fixed.to_vec();
            uv.push((pu, pv));
            uv.extend((0..7).map(|_| (unit(), unit())));
            let u = Packet::new(std::array::from_fn(|i| uv[i].0));
            let v = Packet::new(std::array::from_fn(|i| uv[i].1));
            for (s, fast) in &covered {
                let sl = fast.lanes(s, &hl, &q, u, v, 16.0, 0xffff);
                rays += 16;
                if let Some(ray) = crate::simd::shadow_cull::lanes_meeting(&sl, center, radius) {
                    panic!(
                        "case {case}: {ray:?} meets the sphere {center} {radius} said clear \
                         of {q:?} from the group box {b:?}"
                    );
                }
            }
        }
        // Nothing finite: no box; NaN in the inputs of the cull: nothing clear.
        let nan = V3::splat(Vec3::NAN);
        let one = V3::splat(Vec3::Y);
        assert_eq!(OriginBox::of_group(nan, one, one, 0xffff), None);
        assert_eq!(
            OriginBox::of_group(one, one, V3::splat(Vec3::ZERO), 0xffff),
            None
        );
        assert_eq!(OriginBox::of_group(one, one, one, 0), None);
        let q = QuadLight::new(Vec3::Y * 4.0, Vec3::X, Vec3::Z, Vec3::ONE);
        let far = Vec3::new(0.0, -50.0, 0.0);
        assert!(QuadCull::new((DVec3::ZERO, 0.0), &q).is_some_and(|c| c.clear(far, 1.0)));
        assert!(QuadCull::new((DVec3::NAN, 0.0), &q).is_none());
        assert!(QuadCull::new((DVec3::ZERO, f64::NAN), &q).is_none());
        assert!(QuadCull::new((DVec3::ZERO, -1.0), &q).is_none());
        let b = OriginBox::of([Vec3::ZERO, Vec3::ONE]).expect("finite");
        assert!(!b.covers([Vec3::ZERO, Vec3::NAN]));
        assert_eq!(OriginBox::of([Vec3::ZERO, Vec3::NAN]), None);
        eprintln!(
            "{clear} of {cases} groups clear ({close} pushed out by < 1e-4, {spread_clear} \
             spread over the scene), {members} members, {rays} rays"
        );
        assert!(
            clear > cases / 5 && close > 200 && spread_clear > 5,
            "{clear} clear, {close} close, {spread_clear} spread"
        );
    }

    /// What `settle_near_spheres` relies on in `sphere_roots_for`: on the lanes of
    /// `active` it answers as `sphere_roots` does, bit for bit (roots and bits), or,
    /// where it skips the roots, no lane of `active` had any. Random lane groups of
    /// shadow-like segments (origins near a floor, towards points above it) against
    /// random spheres, each with a random set of active lanes; both outcomes must occur.
    #[test]
    fn sphere_roots_for_answers_as_sphere_roots_on_the_active_lanes() {
        let mut next = xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut skipped, mut computed, mut with_roots) = (0, 0, 0);
        for case in 0..4000 {
            let mut r3 = |s: f32| Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s;
            let centre = r3(4.0) + Vec3::new(0.0, 1.5, 0.0);
            let radius = 0.1 + (r3(1.0).x + 0.5) * 1.5;
            let light = Vec3::new(0.0, 6.0, 0.0) + r3(6.0);
            let spread = [0.05f32, 1.0, 8.0][case % 3];
            let around = r3(8.0) * Vec3::new(1.0, 0.0, 1.0);
            let mut o = [[0.0f32; 16]; 3];
            let mut d = [[0.0f32; 16]; 3];
            for l in 0..16 {
                let p = around + r3(spread) * Vec3::new(1.0, 0.0, 1.0);
                let dir = light + r3(0.5) - p;
                for c in 0..3 {
                    (o[c][l], d[c][l]) = (p[c], dir[c]);
                }
            }
            let lanes = RayLanes {
                o: o.map(Packet::new),
                d: d.map(Packet::new),
                tmin: Packet::splat(0.0),
            };
            let active = (next_mask(unit()) & 0xffff).max(1);
            let (lo, hi, bits) = sphere_roots(&lanes, centre, radius);
            let (flo, fhi, fbits) = sphere_roots_for(&lanes, centre, radius, active);
            assert!(
                fbits != 0 || bits & active == 0,
                "no roots where lanes {:#x} have some",
                bits & active
            );
            if fbits == 0 {
                skipped += 1;
                continue;
            }
            computed += 1;
            assert_eq!(fbits, bits, "bits");
            with_roots += (bits & active != 0) as usize;
            for l in (0..16).filter(|l| active >> l & 1 == 1) {
                let pair =
                    |a: Packet, b: Packet| (a.to_array()[l].to_bits(), b.to_array()[l].to_bits());
                assert_eq!(pair(flo, fhi), pair(lo, hi), "lane {l}");
            }
        }
        eprintln!("{skipped} skipped, {computed} computed ({with_roots} with roots)");
        assert!(skipped > 500 && with_roots > 500, "{skipped} {with_roots}");
    }

    /// A lane mask from a uniform number in `[0, 1)`.
    fn next_mask(u: f32) -> u32 {
        (u * 65536.0) as u32
    }
}
