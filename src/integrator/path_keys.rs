//! Random numbers keyed by path identity: the stream of a shading point
//! ([`path_rng`]), the identity of a child ray ([`child_path`]), and the per-hit sample
//! sets (light points, lobe directions) drawn from them (`hit_points`). Keyed by
//! identity, not by visiting order, so the depth-first and the breadth-first
//! integrators draw the same samples.

use super::SamplerKind;
use super::sampling::{Dimension, PixelRng, append_2d_split, fill_2d, pad_to_lanes};
use super::sobol::{SobolDim, SobolSet};

/// Which per-hit set a shading point draws: its pixel, path and depth, and what the
/// points are for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HitSet {
    pub seed: u64,
    pub pixel: u64,
    pub path: u64,
    pub depth: u32,
    pub dim: SobolDim,
}

/// Fills `out` with the `n` points of a per-hit set (light points, lobe directions).
/// With the Sobol sampler, at the first hit of a camera ray (`depth == 0`, where the
/// path identity is the camera ray's index `c` in its pixel) the points are
/// `c n .. c n + n` of the pixel's sequence for `dim`: one set stratified across all of
/// the pixel's camera rays, so that one shadow point per eye sample still covers the
/// light evenly over the pixel. Everywhere else the set is drawn from the shading
/// point's own stream ([`path_rng`], created on first use).
pub(crate) fn hit_points(
    sampler: SamplerKind,
    set: HitSet,
    n: u32,
    stream: &mut Option<PixelRng>,
    out: &mut Vec<(f32, f32)>,
) {
    if sampler == SamplerKind::Sobol && set.depth == 0 {
        let seq = SobolSet::new(set.seed, set.pixel, set.dim);
        let first = (set.path as u32).wrapping_mul(n);
        out.clear();
        out.extend((0..n).map(|i| seq.point(first.wrapping_add(i))));
        return;
    }
    let rng = stream.get_or_insert_with(|| path_rng(set.seed, set.pixel, set.path));
    fill_2d(sampler, n, Dimension::Hit, false, rng, out);
}

/// [`hit_points`] into two arrays, `u` the first coordinates and `v` the second, each
/// padded with zeros to a multiple of 16 (the area-light stage's lanes): the same
/// points bit for bit, drawing the same numbers from `stream` (`pairs` is scratch).
pub(crate) fn hit_points_split(
    sampler: SamplerKind,
    set: HitSet,
    n: u32,
    stream: &mut Option<PixelRng>,
    (u, v): (&mut Vec<f32>, &mut Vec<f32>),
    pairs: &mut Vec<(f32, f32)>,
) {
    u.clear();
    v.clear();
    hit_points_append(sampler, set, n, stream, (u, v), pairs);
    pad_to_lanes(u);
    pad_to_lanes(v);
}

/// [`hit_points_split`] appended after what `u` and `v` hold, without padding: a pack
/// of shading points (`area_light::shade_quads_packed`) puts its points' sets side by
/// side, each at its block of lanes, without a copy per point.
pub(crate) fn hit_points_append(
    sampler: SamplerKind,
    set: HitSet,
    n: u32,
    stream: &mut Option<PixelRng>,
    (u, v): (&mut Vec<f32>, &mut Vec<f32>),
    pairs: &mut Vec<(f32, f32)>,
) {
    if sampler == SamplerKind::Sobol && set.depth == 0 {
        let seq = SobolSet::new(set.seed, set.pixel, set.dim);
        let first = (set.path as u32).wrapping_mul(n);
        for i in 0..n {
            let (a, b) = seq.point(first.wrapping_add(i));
            u.push(a);
            v.push(b);
        }
        return;
    }
    let rng = stream.get_or_insert_with(|| path_rng(set.seed, set.pixel, set.path));
    append_2d_split(sampler, n, Dimension::Hit, rng, (u, v), pairs);
}

/// The random stream of the shading point reached by path `path` of pixel `pixel`.
/// Keyed by identity, not by visiting order, so a depth-first and a breadth-first
/// traversal of the same ray tree draw the same numbers. Distinct from the pixel's own
/// stream (`PixelRng::new(seed, pixel)`), which draws the camera samples.
pub fn path_rng(seed: u64, pixel: u64, path: u64) -> PixelRng {
    PixelRng::new(
        seed ^ PATH_STREAM,
        pixel ^ path.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(32),
    )
}

/// Identity of the `branch`-th child ray emitted at the shading point of `parent`.
#[inline]
pub fn child_path(parent: u64, branch: u32) -> u64 {
    // SplitMix64's finaliser spreads consecutive inputs over the whole range.
    let mut z = parent
        .wrapping_add(branch as u64 + 1)
        .wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 30)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 27)
}

/// Separates the shading-point streams from the pixel streams of the same seed.
const PATH_STREAM: u64 = 0x5bd1_e995_7f4a_7c15;

#[cfg(test)]
mod tests {
    use super::*;

    /// Sobol sampler they form a (0,4,2)-net (one point in every elementary interval
    /// of area 1/16), so the light is covered evenly across the pixel. The jittered
    /// sampler (the behaviour before the Sobol sampler) draws each camera ray's single
    /// point on its own, which is checked to fail the same test in most pixels.
    #[test]
    fn sobol_light_points_are_stratified_across_the_pixels_camera_rays() {
        let points = |sampler, pixel| -> Vec<(f32, f32)> {
            let mut out = Vec::new();
            (0..16u64)
                .map(|path| {
                    let set = HitSet {
                        seed: 3,
                        pixel,
                        path,
                        depth: 0,
                        dim: SobolDim::Light(0),
                    };
                    hit_points(sampler, set, 1, &mut None, &mut out);
                    out[0]
                })
                .collect()
        };
        let pixels = 64;
        for p in 0..pixels {
            let pts = points(SamplerKind::Sobol, p);
            assert!(
                crate::integrator::sobol::is_0m2_net(&pts),
                "pixel {p}: {pts:?}"
            );
        }
        let jittered_nets = (0..pixels)
            .filter(|&p| crate::integrator::sobol::is_0m2_net(&points(SamplerKind::Jittered, p)))
            .count();
        assert!(jittered_nets < 4, "{jittered_nets} jittered nets");
        // Deeper hits keep a set of their own per shading point.
        let deep = |path| {
            let mut out = Vec::new();
            let set = HitSet {
                seed: 3,
                pixel: 0,
                path,
                depth: 1,
                dim: SobolDim::Light(0),
            };
            hit_points(SamplerKind::Sobol, set, 16, &mut None, &mut out);
            out
        };
        assert!(crate::integrator::sobol::is_0m2_net(&deep(12345)));
        assert_ne!(deep(12345), deep(12346));
    }

    /// The light points as lanes (`hit_points_split`, the area-light stage's) are
    /// `hit_points`' points bit for bit, in order, padded with zeros to a multiple of
    /// 16, and leave the shading point's stream where `hit_points` leaves it: every
    /// sampler, at the first hit (the Sobol pixel sequence) and deeper (the path's
    /// stream, created on first use or already drawn from), square and other counts.
    #[test]
    fn light_points_as_lanes_equal_the_pairs() {
        let mut compared = 0;
        for &sampler in SamplerKind::ALL {
            for depth in [0, 1] {
                for n in [1u32, 2, 3, 4, 9, 15, 16, 17, 36, 64, 100, 256] {
                    for path in [0u64, 5, 77] {
                        let set = HitSet {
                            seed: 11,
                            pixel: 40 + path,
                            path,
                            depth,
                            dim: SobolDim::Light(1),
                        };
                        // A fresh stream, and one already drawn from (a second light).
                        for warm in [false, true] {
                            let start = warm.then(|| {
                                let mut r = path_rng(1, 2, path);
                                r.next_u64();
                                r
                            });
                            let (mut a, mut b) = (start.clone(), start);
                            let mut pairs = Vec::new();
                            hit_points(sampler, set, n, &mut a, &mut pairs);
                            let (mut u, mut v, mut scratch) = (Vec::new(), Vec::new(), Vec::new());
                            hit_points_split(
                                sampler,
                                set,
                                n,
                                &mut b,
                                (&mut u, &mut v),
                                &mut scratch,
                            );
                            let len = (n as usize).next_multiple_of(16);
                            assert_eq!((u.len(), v.len()), (len, len));
                            for (i, &(x, y)) in pairs.iter().enumerate() {
                                assert_eq!(
                                    (u[i].to_bits(), v[i].to_bits()),
                                    (x.to_bits(), y.to_bits()),
                                    "{sampler} depth {depth} n {n} point {i}"
                                );
                            }
                            assert!(
                                u[n as usize..]
                                    .iter()
                                    .chain(&v[n as usize..])
                                    .all(|&z| z == 0.0)
                            );
                            assert_eq!(
                                a.map(|mut r| r.next_u64()),
                                b.map(|mut r| r.next_u64()),
                                "{sampler} depth {depth} n {n}: the stream after"
                            );
                            compared += pairs.len();
                        }
                    }
                }
            }
        }
        assert!(compared > 10_000, "{compared} points");
    }
}
