//! Camera rays lane-parallel: the SIMD twin of [`CameraFrame::ray`] followed by
//! [`LensFrame::ray`] (pinhole or orthographic projection, thin lens, moving eye,
//! shutter time), one ray per lane.
//!
//! Every lane performs the scalar code's operations in the same order (glam's `Vec3`
//! is plain `f32` arithmetic, `normalize` is `v * (1 / sqrt(dot(v, v)))` with the dot
//! product summed x, y, z; Rust never fuses a multiply and an add, and division and
//! square root are correctly rounded in both), so the rays agree bit for bit with the
//! scalar oracle. `tests/` and the unit test below check that.

use super::Lanes;
use crate::geometry::Ray;
use crate::scene::{CameraFrame, LensFrame};

/// `WIDTH` rays as lanes: origin, direction, time (`tmin = 0`, `tmax = inf`, as
/// [`Ray::new`]).
#[derive(Clone, Copy)]
pub struct RayLanes<L: Lanes> {
    pub origin: [L; 3],
    pub dir: [L; 3],
    pub time: L,
}

impl<L: Lanes> RayLanes<L> {
    /// Appends lanes `0..n` (at most `WIDTH`) to `out` as [`Ray`]s
    /// ([`super::ray_store::append_rays`]: nine window stores per sixteen rays with
    /// AVX-512, an 8x8 transpose per eight rays with AVX2). Inlined with it into the
    /// caller's loop, so that the lanes reach the stores in registers (a call took
    /// them through the stack).
    ///
    /// Before, a loop over the component arrays cut to `n` (callgrind, bunny
    /// 1024x1024, 1 thread: `block_rays` 90.6 M -> 72.8 M instructions for 1,048,576
    /// rays against indexing uncut arrays); that loop is now the reference.
    #[inline(always)]
    pub fn append(&self, n: usize, out: &mut Vec<Ray>) {
        let n = n.min(L::WIDTH);
        let o = self.origin.map(L::to_array);
        let d = self.dir.map(L::to_array);
        let t = self.time.to_array();
        super::ray_store::append_rays(
            [o[0].as_ref(), o[1].as_ref(), o[2].as_ref()],
            [d[0].as_ref(), d[1].as_ref(), d[2].as_ref()],
            t.as_ref(),
            n,
            out,
        );
    }
}

#[inline(always)]
fn splat3<L: Lanes>(v: glam::Vec3) -> [L; 3] {
    [L::splat(v.x), L::splat(v.y), L::splat(v.z)]
}

/// `v * (1 / |v|)`, glam's `Vec3::normalize` lane by lane.
#[inline(always)]
fn normalize<L: Lanes>(v: [L; 3]) -> [L; 3] {
    let dot = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let r = L::splat(1.0) / dot.sqrt();
    [v[0] * r, v[1] * r, v[2] * r]
}

/// The camera rays through the image points `(px, py)` (pixel centres at +0.5), with
/// the aperture points `lens` (already warped onto the unit aperture, as
/// [`crate::geometry::warp::sample_aperture`] returns them; `None`: pinhole) and the
/// shutter times `time`: lane `i` equals
/// `lens_frame.ray(frame, frame.ray(px[i], py[i]), lens[i], time[i])` bit for bit.
#[inline(always)]
pub fn camera_rays<L: Lanes>(
    frame: &CameraFrame,
    lens_frame: &LensFrame,
    px: L,
    py: L,
    lens: Option<(L, L)>,
    time: L,
) -> RayLanes<L> {
    let (w, h) = (L::splat(frame.width), L::splat(frame.height));
    let (one, two) = (L::splat(1.0), L::splat(2.0));
    let right = splat3::<L>(frame.right);
    let up = splat3::<L>(frame.up);
    let forward = splat3::<L>(frame.forward);
    let eye = splat3::<L>(frame.eye);
    let (mut origin, mut dir);
    if let Some(hh) = frame.ortho_half_height {
        let hh = L::splat(hh);
        let sx = (two * px / w - one) * hh * w / h;
        let sy = (one - two * py / h) * hh;
        origin = [0, 1, 2].map(|a| eye[a] + sx * right[a] + sy * up[a]);
        dir = forward;
    } else {
        let th = L::splat(frame.tan_half);
        let sx = (two * px / w - one) * th * w / h;
        let sy = (one - two * py / h) * th;
        dir = normalize([0, 1, 2].map(|a| forward[a] + sx * right[a] + sy * up[a]));
        origin = eye;
    }
    if let Some(lens) = lens {
        let focus = focus_point(frame, lens_frame, origin, dir);
        (origin, dir) = through_lens(frame, lens_frame, origin, focus, lens);
    }
    RayLanes {
        origin: moved_eye(lens_frame, origin, time),
        dir,
        time,
    }
}

/// Where the pinhole ray `origin + t dir` meets the plane of focus:
/// `origin + dir (focus_distance / dot(dir, forward))`, as [`LensFrame::ray`].
#[inline(always)]
fn focus_point<L: Lanes>(
    frame: &CameraFrame,
    lens_frame: &LensFrame,
    origin: [L; 3],
    dir: [L; 3],
) -> [L; 3] {
    let forward = splat3::<L>(frame.forward);
    let d_f = dir[0] * forward[0] + dir[1] * forward[1] + dir[2] * forward[2];
    let k = L::splat(lens_frame.focus_distance) / d_f;
    [0, 1, 2].map(|a| origin[a] + dir[a] * k)
}

/// The thin-lens step of [`LensFrame::ray`]: the ray leaves `origin` moved by
/// `aperture (lx right + ly up)` towards `focus`.
#[inline(always)]
fn through_lens<L: Lanes>(
    frame: &CameraFrame,
    lens_frame: &LensFrame,
    origin: [L; 3],
    focus: [L; 3],
    (lx, ly): (L, L),
) -> ([L; 3], [L; 3]) {
    let right = splat3::<L>(frame.right);
    let up = splat3::<L>(frame.up);
    let ap = L::splat(lens_frame.aperture);
    let origin = [0, 1, 2].map(|a| origin[a] + ap * (lx * right[a] + ly * up[a]));
    let dir = normalize([0, 1, 2].map(|a| focus[a] - origin[a]));
    (origin, dir)
}

/// The eye motion step of [`LensFrame::ray`]: `origin` moved by the eye's
/// displacement at `time` (unchanged without a shutter interval or motion).
#[inline(always)]
fn moved_eye<L: Lanes>(lens_frame: &LensFrame, origin: [L; 3], time: L) -> [L; 3] {
    let [s0, s1] = lens_frame.shutter;
    if lens_frame.eye_motion != glam::Vec3::ZERO && s1 > s0 {
        let s = (time - L::splat(s0)) / L::splat(s1 - s0);
        let m = splat3::<L>(lens_frame.eye_motion);
        return [0, 1, 2].map(|a| origin[a] + s * m[a]);
    }
    origin
}

/// The focus points of [`camera_rays`] for a perspective frame: where the pinhole
/// rays through the image points `(px, py)` meet the plane of focus. With
/// [`lens_rays`] they give `camera_rays` with a lens, the same bits: the thin-lens
/// rays of one image point share its focus point, so `CameraSampler::block_rays`
/// computes it once per eye sample rather than once per lens point (the pinhole
/// direction and the focus scale, four divisions and a square root per lane, are
/// most of the lane work).
#[inline(always)]
pub fn focus_points<L: Lanes>(frame: &CameraFrame, lens_frame: &LensFrame, px: L, py: L) -> [L; 3] {
    debug_assert!(frame.ortho_half_height.is_none(), "perspective frames only");
    let (w, h) = (L::splat(frame.width), L::splat(frame.height));
    let (one, two) = (L::splat(1.0), L::splat(2.0));
    let right = splat3::<L>(frame.right);
    let up = splat3::<L>(frame.up);
    let forward = splat3::<L>(frame.forward);
    let th = L::splat(frame.tan_half);
    let sx = (two * px / w - one) * th * w / h;
    let sy = (one - two * py / h) * th;
    let dir = normalize([0, 1, 2].map(|a| forward[a] + sx * right[a] + sy * up[a]));
    focus_point(frame, lens_frame, splat3::<L>(frame.eye), dir)
}

/// The thin-lens camera rays of a perspective frame from their focus points
/// ([`focus_points`]), aperture points `lens` (on the unit aperture) and shutter
/// times: lane `i` equals [`camera_rays`] of the image point whose focus point is
/// `focus[i]`, with `lens[i]` and `time[i]`, bit for bit (the same operations on the
/// same values).
#[inline(always)]
pub fn lens_rays<L: Lanes>(
    frame: &CameraFrame,
    lens_frame: &LensFrame,
    focus: [L; 3],
    lens: (L, L),
    time: L,
) -> RayLanes<L> {
    let (origin, dir) = through_lens(frame, lens_frame, splat3::<L>(frame.eye), focus, lens);
    RayLanes {
        origin: moved_eye(lens_frame, origin, time),
        dir,
        time,
    }
}

/// The pinhole part of [`camera_rays`] from terms computed once per image column and
/// once per image row: `col[a]` is `forward[a] + sx right[a]` of the lane's column,
/// `row[a]` is `sy up[a]` of its row (each rounded once, as there). Lane `i` leaves
/// `eye` along `normalize(col + row)` at `time`: the same sum, in the same order, as
/// [`camera_rays`] without lens and eye motion, so the same bits.
///
/// A camera ray then costs three additions and the normalisation; `sx` and `sy` (two
/// divisions among six operations each) and the six products of the frame are per
/// column and per row (`CameraSampler::block_rays`, 4x4 pixel blocks).
#[inline(always)]
pub fn pinhole_rays<L: Lanes>(eye: glam::Vec3, col: [L; 3], row: [L; 3], time: L) -> RayLanes<L> {
    RayLanes {
        origin: splat3::<L>(eye),
        dir: normalize([col[0] + row[0], col[1] + row[1], col[2] + row[2]]),
        time,
    }
}

/// The column term of [`pinhole_rays`] for the image abscissa `px`: `forward[a] +
/// sx right[a]`, with `sx` as [`camera_rays`] computes it (perspective frames).
#[inline]
pub fn column_term(frame: &CameraFrame, px: f32) -> [f32; 3] {
    let sx = (2.0 * px / frame.width - 1.0) * frame.tan_half * frame.width / frame.height;
    let (f, r) = (frame.forward, frame.right);
    [f.x + sx * r.x, f.y + sx * r.y, f.z + sx * r.z]
}

/// The row term of [`pinhole_rays`] for the image ordinate `py`: `sy up[a]`.
#[inline]
pub fn row_term(frame: &CameraFrame, py: f32) -> [f32; 3] {
    let sy = (1.0 - 2.0 * py / frame.height) * frame.tan_half;
    let u = frame.up;
    [sy * u.x, sy * u.y, sy * u.z]
}

/// [`LensFrame::time`] lane by lane: `open + u (close - open)`.
#[inline]
pub fn shutter_times<L: Lanes>(lens_frame: &LensFrame, u: L) -> L {
    let [s0, s1] = lens_frame.shutter;
    L::splat(s0) + u * L::splat(s1 - s0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;
    use crate::scene::{Camera, CameraEffects};
    use crate::simd::{F4, F16};
    use glam::{Vec2, Vec3};

    fn check<L: Lanes>(effects: CameraEffects) {
        let cam = Camera {
            eye: Vec3::new(0.3, 1.7, 5.2),
            target: Vec3::new(-0.2, 0.4, 0.1),
            up: Vec3::Y,
            vfov_deg: 41.0,
        };
        let frame = cam.frame(97, 61).with_effects(&effects);
        let lf = LensFrame::new(&cam, &effects);
        let mut rng = PixelRng::new(7, 11);
        for _ in 0..200 {
            let mut a = [[0.0f32; 16]; 5];
            for l in 0..L::WIDTH {
                let draws = [
                    rng.next_f32() * 97.0,
                    rng.next_f32() * 61.0,
                    2.0 * rng.next_f32() - 1.0,
                    2.0 * rng.next_f32() - 1.0,
                    rng.next_f32(),
                ];
                for (lane, d) in a.iter_mut().zip(draws) {
                    lane[l] = d;
                }
            }
            let time = shutter_times(&lf, L::load(&a[4]));
            let lens = effects
                .has_depth_of_field()
                .then(|| (L::load(&a[2]), L::load(&a[3])));
            let lanes = camera_rays(&frame, &lf, L::load(&a[0]), L::load(&a[1]), lens, time);
            let mut got = Vec::new();
            lanes.append(L::WIDTH, &mut got);
            // Perspective with a lens: also through the focus points, the same bits.
            let mut split = Vec::new();
            if let (Some(lens), None) = (lens, frame.ortho_half_height) {
                let focus = focus_points(&frame, &lf, L::load(&a[0]), L::load(&a[1]));
                lens_rays(&frame, &lf, focus, lens, time).append(L::WIDTH, &mut split);
                assert_eq!(split.len(), L::WIDTH);
            }
            for (l, g) in got.iter().enumerate() {
                let lp = lens.map(|_| Vec2::new(a[2][l], a[3][l]));
                let want = lf.ray(&frame, frame.ray(a[0][l], a[1][l]), lp, lf.time(a[4][l]));
                // Bit for bit: same operations in the same order.
                assert_eq!(
                    (
                        g.origin.to_array().map(f32::to_bits),
                        g.dir.to_array().map(f32::to_bits)
                    ),
                    (
                        want.origin.to_array().map(f32::to_bits),
                        want.dir.to_array().map(f32::to_bits)
                    ),
                    "lane {l}: {g:?} vs {want:?}"
                );
                assert_eq!(g.time.to_bits(), want.time.to_bits());
                assert_eq!((g.tmin, g.tmax), (want.tmin, want.tmax));
                if let Some(s) = split.get(l) {
                    let bits = Ray::bits;
                    assert_eq!(
                        bits(s),
                        bits(&want),
                        "lane {l} (focus points): {s:?} vs {want:?}"
                    );
                }
            }
        }
    }

    /// The per-column and per-row terms summed in lanes give the scalar pinhole rays
    /// bit for bit, at random image points and at every pixel centre of a small
    /// image, for both packet widths.
    #[test]
    fn pinhole_terms_give_the_scalar_camera_rays_bit_for_bit() {
        let cam = Camera {
            eye: Vec3::new(0.3, 1.7, 5.2),
            target: Vec3::new(-0.2, 0.4, 0.1),
            up: Vec3::Y,
            vfov_deg: 41.0,
        };
        let frame = cam.frame(97, 61);
        let lf = LensFrame::new(&cam, &CameraEffects::default());
        let mut rng = PixelRng::new(3, 5);
        let mut points: Vec<(f32, f32)> = (0..61 * 97)
            .map(|i| ((i % 97) as f32 + 0.5, (i / 97) as f32 + 0.5))
            .collect();
        points.extend((0..4000).map(|_| (rng.next_f32() * 97.0, rng.next_f32() * 61.0)));
        fn run<L: Lanes>(frame: &CameraFrame, lf: &LensFrame, points: &[(f32, f32)]) {
            for chunk in points.chunks_exact(L::WIDTH) {
                let mut terms = [[0.0f32; 16]; 6];
                for (l, &(px, py)) in chunk.iter().enumerate() {
                    let (c, r) = (column_term(frame, px), row_term(frame, py));
                    for a in 0..3 {
                        terms[a][l] = c[a];
                        terms[3 + a][l] = r[a];
                    }
                }
                let col = [0, 1, 2].map(|a| L::load(&terms[a]));
                let row = [3, 4, 5].map(|a| L::load(&terms[a]));
                let mut got = Vec::new();
                pinhole_rays(frame.eye, col, row, L::splat(lf.shutter[0]))
                    .append(L::WIDTH, &mut got);
                for (g, &(px, py)) in got.iter().zip(chunk) {
                    let want = lf.ray(frame, frame.ray(px, py), None, lf.shutter[0]);
                    let bits = |r: &crate::geometry::Ray| {
                        [
                            r.origin.to_array(),
                            r.dir.to_array(),
                            [r.tmin, r.tmax, r.time],
                        ]
                        .map(|a| a.map(f32::to_bits))
                    };
                    assert_eq!(bits(g), bits(&want), "({px}, {py}): {g:?} vs {want:?}");
                }
            }
        }
        run::<F4>(&frame, &lf, &points);
        run::<F16>(&frame, &lf, &points);
    }

    #[test]
    fn lane_camera_rays_equal_the_scalar_camera_bit_for_bit() {
        let lens = CameraEffects {
            aperture: 0.2,
            focus_distance: Some(3.5),
            ..Default::default()
        };
        let motion = CameraEffects {
            shutter: [0.25, 1.5],
            eye1: Some(Vec3::new(0.5, 1.5, 4.0)),
            ..lens
        };
        let ortho = CameraEffects {
            ortho_height: Some(2.5),
            shutter: [0.0, 1.0],
            eye1: Some(Vec3::new(0.5, 1.5, 4.0)),
            ..Default::default()
        };
        let ortho_lens = CameraEffects {
            ortho_height: Some(2.5),
            ..motion
        };
        for e in [CameraEffects::default(), lens, motion, ortho, ortho_lens] {
            check::<F4>(e);
            check::<F16>(e);
        }
    }
}
