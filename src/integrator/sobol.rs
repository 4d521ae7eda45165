//! The `sobol` sampler: per pixel and per dimension, an Owen-scrambled Sobol
//! (0,2)-sequence indexed by the sample's index in the pixel ("padded" sampling, as
//! pbrt-v4's `PaddedSobolSampler`, Pharr, Jakob, Humphreys 2023, §8.7), so that every
//! dimension (pixel position, lens point, shutter time, the light points and lobe
//! directions of the first hit) is stratified across *all* of a pixel's samples, and
//! every power-of-two prefix of a pixel's samples is itself a (0,m,2)-net.
//!
//! - Points: the first two Sobol dimensions (van der Corput, and the Pascal-matrix
//!   dimension), which together form a (0,2)-sequence in base 2 (Sobol 1967): its first
//!   `2^m` points put exactly one point in every elementary interval of area `2^-m`.
//! - Scrambling: Owen's nested uniform scrambling (Owen 1995), hashed per prefix of
//!   bits by the Laine-Karras hash (Burley 2020): keeps the net property, makes every single
//!   point uniform in `[0, 1)²` (so every estimate is unbiased) and decorrelates pixels.
//!   Each dimension of each pixel has its own scramble (padding).
//! - Decorrelation of dimensions: with the same index `i` in two independently
//!   scrambled copies of one sequence, the samples that are close in one dimension are
//!   close in the other (scrambling permutes the intervals but keeps which points share
//!   one). pbrt shuffles the index by a random permutation of `0..spp`, which would break
//!   the prefix property; here the index is permuted by [`shuffle_index`], a random
//!   permutation that maps every `0..2^k` onto itself: bit `j` of the index is flipped by
//!   a hash of the bits above it, and never when those are all zero.
//!
//! Measured on `scenes/dof_area.toml` (128 x 128, 1 shadow ray per eye sample, display
//! RMSE against a 1024 x 16 jittered reference, `packet-render converge`,
//! docs/convergence.md): 0.00348 at 64 samples against jittered's 0.00551 (1.58x
//! lower), 0.00770 against 0.01140 at 16, 0.01786 against 0.02406 at 4.

/// Which set a point belongs to; each has its own scramble and index shuffle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SobolDim {
    Pixel,
    Lens,
    Time,
    /// The points on light `i` (index in `Scene::lights`) at a camera ray's first hit.
    Light(u32),
    /// Glossy lobe directions at a camera ray's first hit.
    Glossy,
    /// Translucent lobe directions at a camera ray's first hit.
    Translucency,
    /// Directions towards the environment at a camera ray's first hit.
    Environment,
}

impl SobolDim {
    fn tag(self) -> u64 {
        match self {
            SobolDim::Pixel => 1,
            SobolDim::Lens => 2,
            SobolDim::Time => 3,
            SobolDim::Glossy => 4,
            SobolDim::Translucency => 5,
            SobolDim::Environment => 6,
            SobolDim::Light(i) => 16 + i as u64,
        }
    }
}

/// The scramble of one dimension of one pixel: two 64-bit keys (one per coordinate)
/// and one for the index shuffle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SobolSet {
    keys: [u64; 3],
}

impl SobolSet {
    /// The set of dimension `dim` of pixel `pixel` for render seed `seed`.
    pub fn new(seed: u64, pixel: u64, dim: SobolDim) -> Self {
        let base = mix64(mix64(seed ^ SOBOL_STREAM) ^ mix64(pixel.wrapping_add(GOLDEN)));
        let base = mix64(base ^ dim.tag().wrapping_mul(GOLDEN));
        SobolSet {
            keys: [
                mix64(base.wrapping_add(GOLDEN)),
                mix64(base.wrapping_add(GOLDEN.wrapping_mul(2))),
                mix64(base.wrapping_add(GOLDEN.wrapping_mul(3))),
            ],
        }
    }

    /// A set scrambled by three 64-bit keys (for the per-shading-point sets of deeper
    /// hits, whose keys come from the path's random stream).
    pub fn from_keys(keys: [u64; 3]) -> Self {
        SobolSet { keys }
    }

    /// The `i`-th point of the set, in `[0, 1)²`.
    #[inline]
    pub fn point(&self, i: u32) -> (f32, f32) {
        let j = shuffle_index(i, self.keys[2]);
        let (x, y) = sobol_2d(j);
        (
            to_unit(owen_scramble(x, self.keys[0])),
            to_unit(owen_scramble(y, self.keys[1])),
        )
    }

    /// The `i`-th value of the 1D set (the first coordinate: a scrambled van der
    /// Corput sequence, a (0,1)-sequence).
    #[inline]
    pub fn value(&self, i: u32) -> f32 {
        let j = shuffle_index(i, self.keys[2]);
        to_unit(owen_scramble(j.reverse_bits(), self.keys[0]))
    }
}

/// Separates the Sobol scrambles from the other streams of the same seed.
const SOBOL_STREAM: u64 = 0x2545_f491_4f6c_dd1d;
const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// The first two dimensions of the Sobol sequence at index `i`, as 32-bit fractions:
/// the van der Corput radical inverse (the identity generator matrix, bit-reversed) and
/// the Pascal matrix mod 2 (direction numbers `v_0 = 2^31`, `v_k = v_{k-1} ^ (v_{k-1} >> 1)`).
#[inline]
pub fn sobol_2d(i: u32) -> (u32, u32) {
    let mut y = 0u32;
    let mut v = 1u32 << 31;
    let mut bits = i;
    while bits != 0 {
        if bits & 1 != 0 {
            y ^= v;
        }
        bits >>= 1;
        v ^= v >> 1;
    }
    (i.reverse_bits(), y)
}

/// Owen's nested uniform scramble of a 32-bit fraction (Owen 1995), by the hash of
/// Laine and Karras (2011) on the reversed bits, as Burley ("Practical Hash-based Owen
/// Scrambling", JCGT 2020) does: in the reversed word, the hash flips each bit by a
/// function of the bits below it, i.e. each bit of the fraction by a function of the
/// bits above it. Points that share their top `k` bits keep sharing them (so nets stay
/// nets), and each point alone becomes uniform. (pbrt-v4's `OwenScrambler`, one hash
/// per bit, cost 3x the render time per sample here: dead end, see docs.)
#[inline]
pub fn owen_scramble(v: u32, key: u64) -> u32 {
    laine_karras(v.reverse_bits(), key).reverse_bits()
}

/// Laine-Karras permutation with Vegdahl's constants (as in Burley 2020): every
/// operation changes bit `b` only by a function of the bits below it.
#[inline]
fn laine_karras(mut x: u32, key: u64) -> u32 {
    let seed = (key ^ (key >> 32)) as u32;
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// A random permutation of the indices that maps every `0..2^k` onto itself: bit `j`
/// of `i` is flipped by a hash of the bits above `j` (and the key) when those are not
/// all zero. The flip of a bit depends only on higher bits, so the map is invertible
/// from the top down, and an index below `2^k` never gains a bit at or above `k`.
/// Computed as a nested scramble of the reversed index (`laine_karras`) whose flips
/// at and below the lowest set bit of the reversed index are masked off.
#[inline]
pub fn shuffle_index(i: u32, key: u64) -> u32 {
    let x = i.reverse_bits();
    if x == 0 {
        return 0;
    }
    let flips = laine_karras(x, key.rotate_left(17)) ^ x;
    let keep = (!0u32).checked_shl(x.trailing_zeros() + 1).unwrap_or(0);
    (x ^ (flips & keep)).reverse_bits()
}

/// The top 24 bits as an f32 in `[0, 1)`, exact.
#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// SplitMix64's output function (Stafford's "Mix13" variant).
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// True when `points` (2^m of them) put exactly one point in every elementary
/// interval `[a 2^-p, (a+1) 2^-p) x [b 2^-q, (b+1) 2^-q)` with `p + q = m`.
#[cfg(test)]
pub(crate) fn is_0m2_net(points: &[(f32, f32)]) -> bool {
    let n = points.len();
    assert!(n.is_power_of_two());
    let m = n.trailing_zeros();
    (0..=m).all(|p| {
        let q = m - p;
        let mut seen = vec![false; n];
        points.iter().all(|&(x, y)| {
            let a = (x * (1u64 << p) as f32) as usize;
            let b = (y * (1u64 << q) as f32) as usize;
            let cell = (a << q) | b;
            !std::mem::replace(&mut seen[cell], true)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unscrambled_points_are_the_sobol_sequence() {
        // Sobol's first points in dimensions 1 and 2, in index (not Gray-code) order.
        let expect = [
            (0.0, 0.0),
            (0.5, 0.5),
            (0.25, 0.75),
            (0.75, 0.25),
            (0.125, 0.625),
            (0.625, 0.125),
        ];
        for (i, &(ex, ey)) in expect.iter().enumerate() {
            let (x, y) = sobol_2d(i as u32);
            assert_eq!(
                (x as f64 / 2f64.powi(32), y as f64 / 2f64.powi(32)),
                (ex, ey),
                "{i}"
            );
        }
    }

    #[test]
    fn every_power_of_two_prefix_is_a_net_in_every_dimension() {
        for pixel in 0..40u64 {
            for dim in [SobolDim::Pixel, SobolDim::Lens, SobolDim::Light(2)] {
                let set = SobolSet::new(7, pixel, dim);
                let pts: Vec<_> = (0..256).map(|i| set.point(i)).collect();
                for m in 0..=8 {
                    assert!(
                        is_0m2_net(&pts[..1 << m]),
                        "pixel {pixel} {dim:?}: first {} points",
                        1 << m
                    );
                }
                // The 1D set: one value in each of the 2^m strata of every prefix.
                let t: Vec<f32> = (0..64).map(|i| set.value(i)).collect();
                for m in 0..=6 {
                    let mut seen = vec![0; 1 << m];
                    for &v in &t[..1 << m] {
                        seen[(v * (1 << m) as f32) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "{dim:?} 1D prefix {m}");
                }
            }
        }
    }

    #[test]
    fn shuffle_is_a_permutation_of_every_power_of_two_prefix() {
        for key in [0u64, 1, 0xdead_beef, u64::MAX] {
            for k in 0..=10 {
                let n = 1u32 << k;
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let j = shuffle_index(i, key);
                    assert!(j < n, "key {key}: {i} -> {j} leaves 0..{n}");
                    assert!(!std::mem::replace(&mut seen[j as usize], true));
                }
            }
        }
        // ... and not the identity: the later blocks are reordered.
        let moved = (0..256).filter(|&i| shuffle_index(i, 99) != i).count();
        assert!(moved > 64, "{moved} of 256 indices moved");
    }

    /// Each point alone is uniform: the mean of `f(x, y) = x y` (integral 1/4) over
    /// point `i` of many pixels' sets. Tolerance: 4 standard errors of the mean of
    /// `x y` (variance 7/144 for independent uniforms) over the pixels.
    #[test]
    fn every_point_is_uniform() {
        let pixels = 20_000u64;
        for i in [0u32, 1, 5, 63] {
            let mut sum = 0.0f64;
            for p in 0..pixels {
                let (x, y) = SobolSet::new(3, p, SobolDim::Lens).point(i);
                sum += x as f64 * y as f64;
            }
            let mean = sum / pixels as f64;
            let se = (7.0f64 / 144.0 / pixels as f64).sqrt();
            assert!((mean - 0.25).abs() < 4.0 * se, "point {i}: {mean}");
        }
    }

    /// Two dimensions of one pixel are not coupled: the samples whose pixel position
    /// is in the left half do not all have their lens point in the same half. With the
    /// bare index (no shuffle) they would, for every pixel (a scramble moves both
    /// halves' points together). Counted over pixels: the first 4 samples' pixel-x
    /// halves against their lens-x halves agree in pattern in about half of the pixels.
    #[test]
    fn dimensions_are_decorrelated() {
        let mut coupled = 0;
        let pixels = 400;
        for p in 0..pixels {
            let a = SobolSet::new(5, p, SobolDim::Pixel);
            let b = SobolSet::new(5, p, SobolDim::Lens);
            // Sample pairs that share a pixel-x quarter: do they share a lens-x quarter?
            let q = |v: f32| (v * 4.0) as u32;
            let same = (0..8u32).all(|i| {
                (0..8u32).all(|j| {
                    q(a.point(i).0) != q(a.point(j).0) || q(b.point(i).0) == q(b.point(j).0)
                })
            });
            coupled += same as u32;
        }
        // Without the shuffle every pixel is coupled (400); measured with it: well
        // under a half.
        assert!(coupled < pixels as u32 / 2, "{coupled} of {pixels} coupled");
    }
}
