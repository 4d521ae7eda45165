//! Rays built in lanes turned into [`Ray`] values (array of structures), as the
//! queues store them: [`lane_rays`] transposes the eight lane vectors `origin`,
//! `dir`, `tmin`, `tmax` in registers (two 8 x 8 transposes, one per half of a
//! 16-lane [`Packet`]), so each ray's first eight fields come out as one vector, then
//! adds its time.
//!
//! `super::ray_store` does the same for camera rays (`tmax` infinite), storing straight
//! into the queue's spare capacity; this one returns the rays as values (no unsafe
//! code) for the shading stage, which picks the lanes to queue.
//!
//! Measured (callgrind, whitted_base 1024x768, 1 thread, instructions of
//! `shade_queue` with everything it calls): 674 M with each queued shadow and child
//! ray built field by field from stored lane arrays (nine scalar loads and stores per
//! ray), 655 M with this transpose.
//!
//! Pure data movement: every field is the lane's value bit for bit (the test below
//! checks it, NaN payloads and signed zeros included).

use super::lanes3::V3;
use super::{F8, Packet};
use crate::geometry::Ray;
use glam::Vec3;
use wide::bytemuck::cast;

// A packet is read as two 8-lane halves, lanes 0..8 first.
const _: () = assert!(std::mem::size_of::<Packet>() == 2 * std::mem::size_of::<F8>());

/// Ray `i` of the result leaves from lane `i` of `origin` along lane `i` of `dir`
/// over `[0, tmax_i]` at `time[i]`.
#[inline(always)]
pub fn lane_rays(origin: &V3, dir: &V3, tmax: Packet, time: &[f32; 16]) -> [Ray; 16] {
    let halves = |p: Packet| -> [F8; 2] { cast(p) };
    let zero = F8::splat(0.0);
    let [ox, oy, oz] = [origin.x, origin.y, origin.z].map(halves);
    let [dx, dy, dz] = [dir.x, dir.y, dir.z].map(halves);
    let t = halves(tmax);
    let mut out = [Ray::new(Vec3::ZERO, Vec3::ZERO); 16];
    for h in 0..2 {
        let rows = F8::transpose([ox[h], oy[h], oz[h], dx[h], dy[h], dz[h], zero, t[h]]);
        for (l, row) in rows.iter().enumerate() {
            let r = row.to_array();
            let i = 8 * h + l;
            out[i] = Ray {
                origin: Vec3::new(r[0], r[1], r[2]),
                dir: Vec3::new(r[3], r[4], r[5]),
                tmin: r[6],
                tmax: r[7],
                time: time[i],
            };
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;

    fn ray_bits(r: &Ray) -> [u32; 9] {
        [
            r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax, r.time,
        ]
        .map(f32::to_bits)
    }

    /// Every field of every ray is its lane's value bit for bit, on random values and
    /// on the special ones (signed zeros, infinities, a NaN with a payload, subnormals).
    #[test]
    fn lane_rays_equal_the_rays_built_lane_by_lane() {
        let mut rng = PixelRng::new(5, 17);
        let special = [
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::from_bits(0x7fc0_1234),
            f32::from_bits(1),
            -f32::MAX,
        ];
        for round in 0..64 {
            let mut value = |k: usize| {
                if (round + k).is_multiple_of(5) {
                    special[(round * 7 + k) % special.len()]
                } else {
                    (rng.next_f32() - 0.5) * 1e3
                }
            };
            let lanes: [[f32; 16]; 8] =
                std::array::from_fn(|f| std::array::from_fn(|l| value(16 * f + l)));
            let v3 = |f: usize| V3::load(&lanes[f], &lanes[f + 1], &lanes[f + 2]);
            let (origin, dir) = (v3(0), v3(3));
            let tmax = Packet::new(lanes[6]);
            let time = lanes[7];
            let got = lane_rays(&origin, &dir, tmax, &time);
            for (i, r) in got.iter().enumerate() {
                let want = Ray {
                    origin: origin.lane(i),
                    dir: dir.lane(i),
                    tmin: 0.0,
                    tmax: lanes[6][i],
                    time: time[i],
                };
                assert_eq!(ray_bits(r), ray_bits(&want), "round {round} lane {i}");
            }
        }
    }
}
