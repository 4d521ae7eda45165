//! Lens points of a polygonal aperture (bokeh blades) from a table of its corners.
//!
//! [`sample_aperture`] computes the two corners of the point's triangle with libm's
//! `cos` and `sin` for every lens point, four calls per camera ray; the corners are
//! the same `blades + 1` values for the whole frame. [`PolygonAperture`] makes them
//! once, with the same expressions, and then does per point what `sample_aperture`
//! does with them (triangle pick, `sqrt`, glam's `lerp`): the same bits (the test
//! below). perf record -e cpu-clock, scenes/dof_area.toml (hexagonal aperture, 16 eye
//! samples) at 960x720, 1 thread, load ~10: `__sincosf_fma` 894 samples -> none; the
//! camera functions with it (`block_rays`, `fill_2d_split`, `fill_2d`,
//! `decorrelate_pairs`) 2487 -> 1549 samples.
//!
//! [`sample_aperture`]: crate::geometry::warp::sample_aperture

use crate::geometry::warp::ONE_MINUS_EPSILON;
use crate::simd::aperture::PolygonLanes;
use crate::simd::{Lanes, PACKET_WIDTH, Packet};
use glam::Vec2;
use std::f32::consts::TAU;

/// The corners `0..=blades` of a polygonal aperture (corner `blades` is corner 0 again,
/// computed from its own angle as `sample_aperture` does).
#[derive(Default)]
pub(crate) struct PolygonAperture {
    blades: u32,
    rotation_bits: u32,
    corners: Vec<Vec2>,
    /// The corners in lanes, where they fit one packet (up to 15 blades).
    lanes: Option<PolygonLanes>,
}

impl PolygonAperture {
    /// The table for `blades` (at least 3) corners rotated by `rotation` radians,
    /// remade only if those differ from the last.
    pub fn update(&mut self, blades: u32, rotation: f32) -> &Self {
        debug_assert!(blades >= 3);
        if self.corners.is_empty()
            || self.blades != blades
            || self.rotation_bits != rotation.to_bits()
        {
            self.corners.clear();
            self.corners.extend((0..=blades).map(|i| {
                let a = rotation + TAU * i as f32 / blades as f32;
                Vec2::new(a.cos(), a.sin())
            }));
            (self.blades, self.rotation_bits) = (blades, rotation.to_bits());
            self.lanes = PolygonLanes::new(&self.corners);
        }
        self
    }

    /// `sample_aperture(u, v, blades, rotation)` from the table.
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> Vec2 {
        let blades = self.blades;
        let x = u * blades as f32;
        let k = (x as u32).min(blades - 1);
        let u = (x - k as f32).min(ONE_MINUS_EPSILON);
        let (a, b) = (self.corners[k as usize], self.corners[k as usize + 1]);
        u.sqrt() * a.lerp(b, v)
    }

    /// Every point `(u[i], v[i])` replaced by its lens point `sample(u[i], v[i])`
    /// (`u`, `v` of one length): sixteen at a time in lanes where the table fits a
    /// packet ([`PolygonLanes`], the same bits), the rest one by one.
    pub fn map_points(&self, u: &mut [f32], v: &mut [f32]) {
        debug_assert_eq!(u.len(), v.len());
        let mut done = 0;
        if let Some(lanes) = &self.lanes {
            for (cu, cv) in u
                .chunks_exact_mut(PACKET_WIDTH)
                .zip(v.chunks_exact_mut(PACKET_WIDTH))
            {
                let (x, y) = lanes.points(Packet::load(cu), Packet::load(cv));
                cu.copy_from_slice(x.to_array().as_ref());
                cv.copy_from_slice(y.to_array().as_ref());
                done += PACKET_WIDTH;
            }
        }
        for (a, b) in u[done..].iter_mut().zip(&mut v[done..]) {
            let p = self.sample(*a, *b);
            (*a, *b) = (p.x, p.y);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::warp::sample_aperture;
    use crate::integrator::sampling::PixelRng;

    /// For 3 to 12 blades and several rotations (negative, large), random points and
    /// the edges of the square (u = 0, u just below 1, u on a triangle boundary):
    /// the table gives `sample_aperture`'s lens points bit for bit.
    #[test]
    fn table_points_equal_sample_aperture_bit_for_bit() {
        let mut rng = PixelRng::new(9, 4);
        let mut table = PolygonAperture::default();
        for blades in 3..=12u32 {
            for rotation in [0.0f32, 0.2618, -1.3, 7.5, std::f32::consts::PI] {
                let t = table.update(blades, rotation);
                let mut pts: Vec<(f32, f32)> = (0..5000)
                    .map(|_| (rng.next_f32(), rng.next_f32()))
                    .collect();
                pts.extend([(0.0, 0.0), (ONE_MINUS_EPSILON, ONE_MINUS_EPSILON)]);
                pts.extend((0..blades).map(|i| (i as f32 / blades as f32, 0.5)));
                for (u, v) in pts {
                    let (got, want) = (t.sample(u, v), sample_aperture(u, v, blades, rotation));
                    assert_eq!(
                        (got.x.to_bits(), got.y.to_bits()),
                        (want.x.to_bits(), want.y.to_bits()),
                        "blades {blades} rotation {rotation} ({u}, {v}): {got} vs {want}"
                    );
                }
            }
        }
    }
    /// [`PolygonAperture::map_points`] (lanes where the table fits a packet, 3 to 15
    /// blades; one by one for 16 and more) against `sample` point by point, bit for
    /// bit: random points, the square's edges and triangle boundaries, and inputs no
    /// sampler gives (negative, one and above, infinite, NaN), over lengths that leave
    /// a partial packet or none.
    #[test]
    fn mapped_points_equal_sample_bit_for_bit() {
        let mut rng = PixelRng::new(17, 2);
        let mut table = PolygonAperture::default();
        let odd = [
            -0.25f32,
            -0.0,
            1.0,
            1.5,
            1e9,
            f32::INFINITY,
            -f32::INFINITY,
            f32::NAN,
            ONE_MINUS_EPSILON,
        ];
        let mut lanes = 0usize;
        for blades in 3..=18u32 {
            for rotation in [0.0f32, 0.2618, -1.3, 7.5] {
                let t = table.update(blades, rotation);
                assert_eq!(t.lanes.is_some(), blades <= 15, "blades {blades}");
                let mut pts: Vec<(f32, f32)> = (0..3000)
                    .map(|_| (rng.next_f32(), rng.next_f32()))
                    .collect();
                pts.extend((0..=blades).map(|i| (i as f32 / blades as f32, 0.5)));
                for &a in &odd {
                    pts.push((a, rng.next_f32()));
                    pts.push((rng.next_f32(), a));
                    pts.push((a, a));
                }
                for len in [pts.len(), 37, 16, 5] {
                    let (mut u, mut v): (Vec<f32>, Vec<f32>) = pts[..len].iter().copied().unzip();
                    t.map_points(&mut u, &mut v);
                    for (i, &(a, b)) in pts[..len].iter().enumerate() {
                        let want = t.sample(a, b);
                        assert_eq!(
                            (u[i].to_bits(), v[i].to_bits()),
                            (want.x.to_bits(), want.y.to_bits()),
                            "blades {blades} rotation {rotation} ({a}, {b}): {} {} vs {want}",
                            u[i],
                            v[i]
                        );
                    }
                    lanes += len;
                }
            }
        }
        assert!(lanes > 150_000, "{lanes}");
    }
}
