//! Sample patterns and warps for distribution ray tracing (Cook, Porter, Carpenter,
//! "Distributed Ray Tracing", SIGGRAPH 1984): pixel positions, lens positions, shutter
//! times, light points and glossy directions.
//!
//! Every set is drawn from the pixel's own random stream ([`PixelRng`]), in a fixed
//! order, so a render is bit-identical for a seed whatever the thread count. A set of
//! `n` points follows the [`SamplerKind`] of the render:
//!
//! - `grid`: the regular `k × k` lattice of cell centres (`k = ceil(sqrt n)`), no
//!   randomness: aliasing instead of noise;
//! - `jittered`: one uniform point per cell of a `k × k` grid for square `n`, N-rooks
//!   (Latin hypercube, Shirley 1991) otherwise;
//! - `random`: independent uniform points;
//! - `halton`: the Halton sequence (bases 2, 3 for pixels, 5, 7 for the lens, 11 for
//!   time, 13, 17 for per-hit sets) shifted by a per-set random Cranley-Patterson
//!   rotation (toroidal shift), so pixels decorrelate and every estimate stays unbiased;
//! - `sobol`: per pixel and dimension, an Owen-scrambled Sobol (0,2)-sequence indexed by
//!   the sample's index in the pixel ([`super::sobol`]): the camera sets and the first
//!   hit's light points and lobe directions are stratified across all of the pixel's
//!   samples, and every power-of-two prefix of them too (progressive rendering). Sets
//!   that belong to no pixel index (deeper hits) are scrambled Sobol sets of their own.

use super::sobol::SobolSet;
use crate::error::{Error, Result};
use crate::geometry::warp::ONE_MINUS_EPSILON;
use crate::simd::splitmix::{GAMMA, MIX1, MIX2};
use std::str::FromStr;

/// Which pattern a render uses for its sample sets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SamplerKind {
    Grid,
    /// Stratified; the default, and what the renderer did before samplers were
    /// selectable (a single pixel sample sits at the pixel centre).
    #[default]
    Jittered,
    Random,
    Halton,
    /// Padded, prefix-stratified Owen-scrambled Sobol ([`super::sobol`]).
    Sobol,
}

impl SamplerKind {
    pub const ALL: &'static [SamplerKind] = &[
        SamplerKind::Grid,
        SamplerKind::Jittered,
        SamplerKind::Random,
        SamplerKind::Halton,
        SamplerKind::Sobol,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Grid => "grid",
            SamplerKind::Jittered => "jittered",
            SamplerKind::Random => "random",
            SamplerKind::Halton => "halton",
            SamplerKind::Sobol => "sobol",
        }
    }
}

/// Pixel reconstruction filter.
///
/// `box`: the mean of the samples inside the pixel. `gaussian`: per-pixel weighted
/// reconstruction: the pixel draws its samples over a 3 × 3 pixel footprint (radius
/// 1.5 px) and weights each by a truncated Gaussian (σ = 0.5 px) of its distance to the
/// pixel centre, dividing by the sum of weights. No splatting into neighbours, so tiles
/// stay independent and renders deterministic; the price is that samples are not
/// shared between pixels (same ray count, wider footprint per pixel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterKind {
    #[default]
    Box,
    Gaussian,
}

impl FilterKind {
    pub const ALL: &'static [FilterKind] = &[FilterKind::Box, FilterKind::Gaussian];

    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Box => "box",
            FilterKind::Gaussian => "gaussian",
        }
    }

    /// Radius of the footprint in pixels.
    pub fn radius(self) -> f32 {
        match self {
            FilterKind::Box => 0.5,
            FilterKind::Gaussian => GAUSSIAN_RADIUS,
        }
    }

    /// Weight of a sample at offset `(dx, dy)` from the pixel centre.
    pub fn weight(self, dx: f32, dy: f32) -> f32 {
        match self {
            FilterKind::Box => 1.0,
            FilterKind::Gaussian => {
                let g = |d2: f32| (-d2 / (2.0 * GAUSSIAN_SIGMA * GAUSSIAN_SIGMA)).exp();
                (g(dx * dx + dy * dy) - g(GAUSSIAN_RADIUS * GAUSSIAN_RADIUS)).max(0.0)
            }
        }
    }
}

const GAUSSIAN_RADIUS: f32 = 1.5;
const GAUSSIAN_SIGMA: f32 = 0.5;

pub(crate) fn parse_named<T: Copy>(
    all: &[T],
    name: fn(T) -> &'static str,
    what: &str,
    s: &str,
) -> Result<T> {
    all.iter().copied().find(|k| name(*k) == s).ok_or_else(|| {
        let names: Vec<_> = all.iter().map(|k| name(*k)).collect();
        Error::parameter(
            what,
            format!("unknown {what} '{s}', expected one of {}", names.join(", ")),
        )
    })
}

impl FromStr for SamplerKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        parse_named(SamplerKind::ALL, SamplerKind::name, "sampler", s)
    }
}

impl FromStr for FilterKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        parse_named(FilterKind::ALL, FilterKind::name, "filter", s)
    }
}

impl std::fmt::Display for SamplerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::fmt::Display for FilterKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which Halton bases a set uses, so that the dimensions of one path never share a
/// base (sharing one would correlate, e.g., lens position with pixel position).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dimension {
    Pixel,
    Lens,
    Time,
    /// Per-hit sets: light points and glossy directions.
    Hit,
}

impl Dimension {
    fn bases(self) -> (u32, u32) {
        match self {
            Dimension::Pixel => (2, 3),
            Dimension::Lens => (5, 7),
            Dimension::Time => (11, 11),
            Dimension::Hit => (13, 17),
        }
    }
}

/// Fills `out` with `n` points in `[0, 1)²` of pattern `kind`. With `centre_single`, a
/// jittered set of one point is the cell centre (the renderer's historical 1-spp pixel
/// position); everywhere else a single point is random, as an estimator needs.
pub fn fill_2d(
    kind: SamplerKind,
    n: u32,
    dim: Dimension,
    centre_single: bool,
    rng: &mut PixelRng,
    out: &mut Vec<(f32, f32)>,
) {
    out.clear();
    match kind {
        SamplerKind::Grid => {
            let k = ceil_sqrt(n);
            let rows = n.div_ceil(k);
            for i in 0..n {
                out.push((
                    ((i % k) as f32 + 0.5) / k as f32,
                    ((i / k) as f32 + 0.5) / rows as f32,
                ));
            }
        }
        SamplerKind::Jittered => {
            let k = n.isqrt();
            if n == 1 && centre_single {
                out.push((0.5, 0.5));
            } else if k * k == n {
                // In lanes, sixteen points at a time (`append_2d_split`'s blocks; the
                // scalar loop, `jittered_square_scalar`, is the tests' oracle).
                //
                // Measured (dof_area 640x480, 1 thread, AVX-512, perf): the scalar loop
                // was 2.3 % of the frame (the camera's 16 pixel positions per pixel).
                let inv = 1.0 / k as f32;
                let (mut i, mut j) = (0u32, 0u32);
                let (mut du, mut dv) = ([0.0f32; 16], [0.0f32; 16]);
                let mut left = n as usize;
                out.reserve(left);
                while left > 0 {
                    let m = left.min(16);
                    rng.fill_pairs16(m, &mut du, &mut dv);
                    let (lu, lv) = crate::simd::jittered::jittered_block((i, j, k), inv, &du, &dv);
                    out.extend(lu[..m].iter().copied().zip(lv[..m].iter().copied()));
                    let next = i + m as u32;
                    (i, j) = (next % k, j + next / k);
                    left -= m;
                }
            } else {
                // N-rooks: n jittered strata in x paired with a permutation of n in y.
                let mut perm: Vec<u32> = (0..n).collect();
                shuffle(&mut perm, rng);
                let inv = 1.0 / n as f32;
                for (i, &j) in perm.iter().enumerate() {
                    let (u, v) = (rng.next_f32(), rng.next_f32());
                    out.push(((i as f32 + u) * inv, (j as f32 + v) * inv));
                }
            }
        }
        SamplerKind::Random => {
            for _ in 0..n {
                out.push((rng.next_f32(), rng.next_f32()));
            }
        }
        SamplerKind::Halton => {
            let (b0, b1) = dim.bases();
            let (r0, r1) = (rng.next_f32(), rng.next_f32());
            for i in 0..n {
                out.push((
                    rotate(radical_inverse(b0, i), r0),
                    rotate(radical_inverse(b1, i), r1),
                ));
            }
        }
        SamplerKind::Sobol => {
            let set = sobol_set_from(rng);
            out.extend((0..n).map(|i| set.point(i)));
        }
    }
}

/// [`fill_2d`] (with `centre_single` false) into two arrays, `u` the first coordinate
/// and `v` the second, each padded with zeros to a multiple of 16 (the lanes of the
/// area-light stage): the same points bit for bit, in the same order, drawing the same
/// numbers from `rng`. A square jittered set (the default sampler's light points) is
/// written straight into the arrays sixteen points at a time: their 32 random numbers
/// drawn in lanes ([`PixelRng::fill_pairs16`], `simd::splitmix`), the points computed
/// in lanes (`simd::jittered`); the other patterns go through `fill_2d` and `pairs`.
///
/// Measured (branch area7; whitted_area64 512x384, 1 thread, AVX-512, process CPU time
/// by `perf stat -e task-clock`, 5 runs interleaved, load 9-13 on 2 cores): 294 ->
/// 270 ms (-8 %); `fill_2d_split` went from 12.8 % to 5.2 % of perf's samples. Before,
/// LLVM already ran `fill_f32`'s draws in AVX-512 lanes (`vpmullq`); what cost was
/// the per-point loop (a conversion, two multiply-adds, two scalar stores per point).
pub fn fill_2d_split(
    kind: SamplerKind,
    n: u32,
    dim: Dimension,
    rng: &mut PixelRng,
    (u, v): (&mut Vec<f32>, &mut Vec<f32>),
    pairs: &mut Vec<(f32, f32)>,
) {
    // The points of `append_2d_split`, then zeros to whole lane groups.
    u.clear();
    v.clear();
    append_2d_split(kind, n, dim, rng, (u, v), pairs);
    pad_to_lanes(u);
    pad_to_lanes(v);
}

/// [`fill_2d`] (with `centre_single` false) appended to two arrays, `u` the first
/// coordinate and `v` the second (`n` points each after what they hold, no padding):
/// the same points bit for bit, in the same order, drawing the same numbers from `rng`
/// as [`fill_2d_split`], a square jittered set in lanes as there (sixteen draws and
/// points at a time). The camera's lens sets go through it straight into the ray
/// staging arrays.
///
/// Measured (whitted_blur16 1024x768, 16 lens points per pixel): the lens set written
/// to its own arrays by `fill_2d_split` and copied into the staging arrays cost, per
/// pixel, two zero fills (`resize`) and four copies of a slice of varying length, each
/// a call to libc's `memset` or `memmove`; here a whole block of sixteen is two stores.
pub fn append_2d_split(
    kind: SamplerKind,
    n: u32,
    dim: Dimension,
    rng: &mut PixelRng,
    (u, v): (&mut Vec<f32>, &mut Vec<f32>),
    pairs: &mut Vec<(f32, f32)>,
) {
    let k = n.isqrt();
    if kind == SamplerKind::Jittered && k * k == n {
        u.reserve(n as usize);
        v.reserve(n as usize);
        let inv = 1.0 / k as f32;
        let (mut i, mut j) = (0u32, 0u32);
        let (mut du, mut dv) = ([0.0f32; 16], [0.0f32; 16]);
        let mut left = n as usize;
        while left > 0 {
            let m = left.min(16);
            rng.fill_pairs16(m, &mut du, &mut dv);
            let (lu, lv) = crate::simd::jittered::jittered_block((i, j, k), inv, &du, &dv);
            if m == 16 {
                // A fixed-length copy: two vector stores, no call.
                u.extend_from_slice(&lu);
                v.extend_from_slice(&lv);
            } else {
                u.extend_from_slice(&lu[..m]);
                v.extend_from_slice(&lv[..m]);
            }
            let next = i + m as u32;
            (i, j) = (next % k, j + next / k);
            left -= m;
        }
    } else {
        fill_2d(kind, n, dim, false, rng, pairs);
        u.extend(pairs.iter().map(|p| p.0));
        v.extend(pairs.iter().map(|p| p.1));
    }
}

/// Zeros up to the next multiple of 16 elements.
pub(crate) fn pad_to_lanes(a: &mut Vec<f32>) {
    a.resize(a.len().next_multiple_of(16), 0.0);
}

/// A scrambled Sobol set keyed by three draws of `rng` (a set of its own, for sets
/// that are not indexed by the sample's index in its pixel).
fn sobol_set_from(rng: &mut PixelRng) -> SobolSet {
    SobolSet::from_keys([rng.next_u64(), rng.next_u64(), rng.next_u64()])
}

/// Fills `out` with `n` values in `[0, 1)` of pattern `kind` (grid: cell centres,
/// jittered: one per stratum, random, or rotated Halton).
pub fn fill_1d(kind: SamplerKind, n: u32, dim: Dimension, rng: &mut PixelRng, out: &mut Vec<f32>) {
    out.clear();
    let inv = 1.0 / n as f32;
    match kind {
        SamplerKind::Grid => out.extend((0..n).map(|i| (i as f32 + 0.5) * inv)),
        SamplerKind::Jittered => {
            for i in 0..n {
                out.push(((i as f32 + rng.next_f32()) * inv).min(ONE_MINUS_EPSILON));
            }
        }
        SamplerKind::Random => {
            for _ in 0..n {
                out.push(rng.next_f32());
            }
        }
        SamplerKind::Halton => {
            let r = rng.next_f32();
            let b = dim.bases().0;
            out.extend((0..n).map(|i| rotate(radical_inverse(b, i), r)));
        }
        SamplerKind::Sobol => {
            let set = sobol_set_from(rng);
            out.extend((0..n).map(|i| set.value(i)));
        }
    }
}

/// Shuffles a set that will be paired with another one (lens with pixel positions,
/// time with both), so that stratum `i` of one set does not always meet stratum `i`
/// of the other (Cook 1986, "Stochastic Sampling in Computer Graphics"). Halton and
/// random sets are already decorrelated by their bases and are left alone.
pub fn decorrelate<T>(kind: SamplerKind, set: &mut [T], rng: &mut PixelRng) {
    if matches!(kind, SamplerKind::Grid | SamplerKind::Jittered) {
        shuffle(set, rng);
    }
}

/// [`decorrelate`] of a set of pairs held as two arrays: the same draws and the same
/// swaps, applied to both.
///
/// A set of sixteen pairs (the camera's 16 lens points per eye sample) takes its swap
/// targets from [`crate::simd::splitmix::shuffle_targets16`] (the fifteen draws in
/// lanes) and swaps each pair as one 64-bit value (`u` in the low half, `v` in the
/// high): the same draws, the same swaps, one swap per step where there were two.
pub fn decorrelate_pairs(kind: SamplerKind, u: &mut [f32], v: &mut [f32], rng: &mut PixelRng) {
    if !matches!(kind, SamplerKind::Grid | SamplerKind::Jittered) {
        return;
    }
    if let (Ok(u), Ok(v)) = (
        <&mut [f32; 16]>::try_from(&mut *u),
        <&mut [f32; 16]>::try_from(&mut *v),
    ) {
        // Tried and not kept (helper fr24, 2026-11-29): the fifteen swaps on sixteen
        // 4-bit indices held in one u64 (no stack array), then one AVX-512 lane
        // permute (`vpermps`) per array; tested bit for bit against these swaps and
        // the images identical. perf, whitted_blur16 1024x768, 1 thread, -F 10000:
        // this function 2.09 % -> 3.05 % of the samples (the nibble swaps are one
        // serial chain of variable shifts), where the reload of `p` below, waiting on
        // the swaps' scalar stores, holds 15 % of its samples.
        let targets = rng.shuffle_targets16();
        let mut p: [u64; 16] =
            std::array::from_fn(|i| u[i].to_bits() as u64 | (v[i].to_bits() as u64) << 32);
        for (m, &j) in targets[..15].iter().enumerate() {
            p.swap(15 - m, j as usize & 15);
        }
        *u = p.map(|x| f32::from_bits(x as u32));
        *v = p.map(|x| f32::from_bits((x >> 32) as u32));
        return;
    }
    shuffle_by(u.len().min(v.len()), rng, |i, j| {
        u.swap(i, j);
        v.swap(i, j);
    });
}

fn shuffle<T>(set: &mut [T], rng: &mut PixelRng) {
    shuffle_by(set.len(), rng, |i, j| set.swap(i, j));
}

/// Fisher-Yates over `n` items, each swap applied by `swap(i, j)`: one sequence of
/// draws for a set however it is stored.
fn shuffle_by(n: usize, rng: &mut PixelRng, mut swap: impl FnMut(usize, usize)) {
    for i in (1..n as u32).rev() {
        let j = rng.below(i + 1);
        swap(i as usize, j as usize);
    }
}

/// Cranley-Patterson rotation: `x + r mod 1`, kept below 1.
#[inline]
fn rotate(x: f32, r: f32) -> f32 {
    let s = x + r;
    let s = if s >= 1.0 { s - 1.0 } else { s };
    s.min(ONE_MINUS_EPSILON)
}

fn ceil_sqrt(n: u32) -> u32 {
    let k = n.isqrt();
    if k * k == n { k } else { k + 1 }
}

/// The van der Corput radical inverse of `i` in base `b`.
pub fn radical_inverse(b: u32, mut i: u32) -> f32 {
    let inv_b = 1.0 / b as f64;
    let mut f = inv_b;
    let mut r = 0.0f64;
    while i > 0 {
        r += (i % b) as f64 * f;
        i /= b;
        f *= inv_b;
    }
    (r as f32).min(ONE_MINUS_EPSILON)
}

/// A per-pixel random stream: SplitMix64 (Steele, Lea, Flood 2014) started from a hash
/// of `(seed, pixel index)`. Independent of which thread renders the pixel, which is
/// what makes images reproducible across thread counts.
#[derive(Clone, Debug)]
pub struct PixelRng {
    state: u64,
}

impl PixelRng {
    pub fn new(seed: u64, pixel: u64) -> Self {
        // Hash both so neighbouring pixels and neighbouring seeds start far apart.
        PixelRng {
            state: mix64(seed ^ mix64(pixel.wrapping_add(GAMMA))),
        }
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GAMMA);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, so every value is exact in f32 and 1.0
    /// can never come out (it would step into the next stratum or pixel).
    ///
    /// The top 24 bits of [`mix64`] are those of its value before the last
    /// `z ^ (z >> 31)` (which changes bits 0..33 only), so that step is left out here
    /// ([`mix64_top24`]): the same numbers, two operations fewer per draw (the light
    /// points of whitted_area64 draw ~200 M of them).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        self.state = self.state.wrapping_add(GAMMA);
        mix64_top24(self.state) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// `out.len()` successive [`next_f32`](Self::next_f32) draws into `out`.
    ///
    /// Dead end (measured): computing each draw on its own from the state advanced
    /// `m + 1` times (`state + (m + 1) γ`), so that LLVM ran the loop in AVX2 lanes
    /// (64-bit multiplies emulated by three `vpmuludq` each, plus one more for the
    /// state), made the whitted_area64 shade stage slower, not faster: 5 interleaved
    /// runs at 1 thread, load ~9 on 2 cores, 8.3-9.8 s against 10.0-11.0 s with it.
    pub fn fill_f32(&mut self, out: &mut [f32]) {
        for o in out {
            *o = self.next_f32();
        }
    }

    /// The next `m <= 16` pairs of [`next_f32`](Self::next_f32) draws, the first of
    /// each pair in `u[..m]` and the second in `v[..m]` (the rest of `u` and `v` holds
    /// the draws after them, which the stream does not advance past): `2m` draws,
    /// computed in lanes where the build has AVX-512DQ (`simd::splitmix`, bit for bit).
    ///
    /// Measured: see `fill_2d_split`.
    #[inline]
    pub fn fill_pairs16(&mut self, m: usize, u: &mut [f32; 16], v: &mut [f32; 16]) {
        debug_assert!(m <= 16);
        crate::simd::splitmix::unit_pairs16(self.skip_pairs(m as u32), u, v);
    }

    /// The state before the next `m` pairs of draws, the stream advanced past them:
    /// for a caller that computes the draws elsewhere (`simd::jittered_pack`, the light
    /// points of several streams in one lane group), as [`fill_pairs16`](Self::fill_pairs16)
    /// advances it.
    #[inline]
    pub fn skip_pairs(&mut self, m: u32) -> u64 {
        let state = self.state;
        self.state = self.state.wrapping_add((2 * m as u64).wrapping_mul(GAMMA));
        state
    }

    /// The swap targets of a Fisher-Yates shuffle of sixteen items, as [`shuffle_by`]
    /// draws them (`below(i + 1)` for `i` from 15 down to 1: entry `m` is step `m`'s),
    /// computed in lanes where the build has AVX-512DQ (`simd::splitmix`, bit for bit);
    /// the stream advances by the fifteen draws. Entry 15 is unspecified.
    #[inline]
    pub fn shuffle_targets16(&mut self) -> [u32; 16] {
        let targets = crate::simd::splitmix::shuffle_targets16(self.state, 16);
        self.state = self.state.wrapping_add(15u64.wrapping_mul(GAMMA));
        targets
    }

    /// The stream's state (what the next draw advances from).
    #[cfg(test)]
    pub(crate) fn state(&self) -> u64 {
        self.state
    }

    /// A stream at the state `state`.
    #[cfg(test)]
    pub(crate) fn from_state(state: u64) -> PixelRng {
        PixelRng { state }
    }

    /// Uniform in `[0, n)` by multiply-shift (Lemire 2019); the bias of at most
    /// `n / 2^32` is irrelevant for shuffling sample strata.
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }
}

/// SplitMix64's output function (Stafford's "Mix13" variant).
fn mix64(z: u64) -> u64 {
    let z = mix64_unfinished(z);
    z ^ (z >> 31)
}

/// [`mix64`] before its last step.
#[inline(always)]
fn mix64_unfinished(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(MIX1);
    (z ^ (z >> 27)).wrapping_mul(MIX2)
}

/// `mix64(z) >> 40`: bits 40..63 of `z ^ (z >> 31)` are bits 40..63 of `z` (the
/// shifted value has nothing above bit 32).
#[inline(always)]
fn mix64_top24(z: u64) -> u64 {
    mix64_unfinished(z) >> 40
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`decorrelate_pairs`] shuffles the two arrays as [`decorrelate`] shuffles the
    /// pairs, and leaves the stream where it does: sixteen pairs (targets in lanes,
    /// pairs swapped as 64-bit values) and other sizes (the scalar loop), every
    /// pattern, NaN and signed zeros among the values.
    #[test]
    fn decorrelated_pairs_equal_decorrelated_sets() {
        for &kind in SamplerKind::ALL {
            for n in [0usize, 1, 2, 5, 15, 16, 17, 32] {
                for seed in 0..50u64 {
                    let mut pairs: Vec<(f32, f32)> = (0..n)
                        .map(|i| (i as f32 * 0.25 - 1.0, -(i as f32) * 3.0 + 0.5))
                        .collect();
                    if n > 3 {
                        pairs[1] = (f32::NAN, -0.0);
                        pairs[2] = (0.0, f32::from_bits(0xffc0_0001));
                    }
                    let (mut u, mut v): (Vec<f32>, Vec<f32>) = pairs.iter().copied().unzip();
                    let (mut a, mut b) = (PixelRng::new(seed, 3), PixelRng::new(seed, 3));
                    decorrelate(kind, &mut pairs, &mut a);
                    decorrelate_pairs(kind, &mut u, &mut v, &mut b);
                    for (i, p) in pairs.iter().enumerate() {
                        let got = (u[i].to_bits(), v[i].to_bits());
                        assert_eq!(
                            got,
                            (p.0.to_bits(), p.1.to_bits()),
                            "{kind} n {n} seed {seed} pair {i}"
                        );
                    }
                    assert_eq!(a.state(), b.state(), "{kind} n {n} seed {seed}");
                }
            }
        }
    }

    /// The square jittered set as `fill_2d` drew it before its lanes: row by row, two
    /// `next_f32` draws per point.
    fn jittered_square_scalar(k: u32, rng: &mut PixelRng, out: &mut Vec<(f32, f32)>) {
        out.clear();
        let inv = 1.0 / k as f32;
        for j in 0..k {
            for i in 0..k {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                out.push(((i as f32 + u) * inv, (j as f32 + v) * inv));
            }
        }
    }

    /// [`fill_2d`]'s square jittered sets (in lanes) are the scalar loop's, bit for
    /// bit, with the stream left where it leaves it: sides 1 to 20 and 33, many
    /// streams, both `centre_single` (a single point at the centre aside).
    #[test]
    fn jittered_squares_equal_the_scalar_loop() {
        let mut checked = 0;
        for k in (1u32..=20).chain([33]) {
            for seed in 0..40u64 {
                for centre in [false, true] {
                    if k == 1 && centre {
                        continue;
                    }
                    let (mut a, mut b) =
                        (PixelRng::new(seed, k as u64), PixelRng::new(seed, k as u64));
                    let (mut got, mut want) = (Vec::new(), Vec::new());
                    fill_2d(
                        SamplerKind::Jittered,
                        k * k,
                        Dimension::Pixel,
                        centre,
                        &mut a,
                        &mut got,
                    );
                    jittered_square_scalar(k, &mut b, &mut want);
                    assert_eq!(got.len(), want.len());
                    for (g, w) in got.iter().zip(&want) {
                        assert_eq!(
                            (g.0.to_bits(), g.1.to_bits()),
                            (w.0.to_bits(), w.1.to_bits()),
                            "k {k} seed {seed}"
                        );
                        checked += 1;
                    }
                    assert_eq!(a.state(), b.state(), "k {k} seed {seed}");
                }
            }
        }
        assert!(checked > 50_000, "{checked}");
    }

    /// [`append_2d_split`] appends [`fill_2d`]'s points (`centre_single` false) bit for
    /// bit after what the arrays hold, and leaves the stream where `fill_2d` does, for
    /// every pattern and for square sets (jittered: in lanes) of fewer, as many and
    /// more points than a block of sixteen, sizes not a multiple of sixteen among them.
    #[test]
    fn appended_split_sets_equal_fill_2d() {
        for &kind in SamplerKind::ALL {
            for n in [
                1u32, 2, 3, 4, 5, 9, 15, 16, 17, 25, 31, 32, 33, 36, 49, 64, 100,
            ] {
                let (mut a, mut b) = (PixelRng::new(5, n as u64), PixelRng::new(5, n as u64));
                let mut want = Vec::new();
                fill_2d(kind, n, Dimension::Lens, false, &mut a, &mut want);
                let head = [0.25f32, -1.0, 7.5];
                let (mut u, mut v) = (head.to_vec(), head.to_vec());
                let mut pairs = Vec::new();
                append_2d_split(
                    kind,
                    n,
                    Dimension::Lens,
                    &mut b,
                    (&mut u, &mut v),
                    &mut pairs,
                );
                assert_eq!(u.len(), 3 + n as usize, "{kind} n {n}");
                assert_eq!(v.len(), 3 + n as usize, "{kind} n {n}");
                assert_eq!(u[..3], head);
                assert_eq!(v[..3], head);
                for (p, w) in want.iter().enumerate() {
                    let got = (u[3 + p].to_bits(), v[3 + p].to_bits());
                    assert_eq!(
                        got,
                        (w.0.to_bits(), w.1.to_bits()),
                        "{kind} n {n} point {p}"
                    );
                }
                assert_eq!(
                    a.state(),
                    b.state(),
                    "{kind} n {n}: the stream moved differently"
                );
            }
        }
    }

    #[test]
    fn stratified_positions_cover_every_stratum() {
        let mut rng = PixelRng::new(7, 3);
        let mut pos = Vec::new();
        for spp in [1u32, 4, 9, 16, 2, 3, 5, 12] {
            fill_2d(
                SamplerKind::Jittered,
                spp,
                Dimension::Pixel,
                true,
                &mut rng,
                &mut pos,
            );
            assert_eq!(pos.len(), spp as usize);
            assert!(
                pos.iter()
                    .all(|&(x, y)| (0.0..1.0).contains(&x) && (0.0..1.0).contains(&y))
            );
            if spp == 1 {
                assert_eq!(pos, vec![(0.5, 0.5)]);
                continue;
            }
            // Both 1D projections hit each of the spp (or k) strata exactly once.
            let k = spp.isqrt();
            let strata = if k * k == spp { k } else { spp };
            for axis in 0..2 {
                let mut count = vec![0u32; strata as usize];
                for &(x, y) in &pos {
                    let c = if axis == 0 { x } else { y };
                    count[(c * strata as f32) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == spp / strata),
                    "spp {spp}: {count:?}"
                );
            }
        }
    }

    /// The first `n` points of a van der Corput sequence in base `b`, for `m` the
    /// largest power of `b` not above `n`, fill the `m` strata of width `1/m` evenly:
    /// each holds `n / m` or `n / m + 1` points (every aligned block of `m` consecutive
    /// indices puts one point in each stratum). A Cranley-Patterson rotation shifts the
    /// block's lattice `{j/m + c}` by the same amount modulo 1, which keeps one point per
    /// stratum. With `m = n` (n a power of b) every stratum holds exactly one.
    fn assert_halton_strata(values: &[f32], b: u32, what: &str) {
        let n = values.len() as u32;
        let mut m = 1;
        while m * b <= n {
            m *= b;
        }
        let mut count = vec![0u32; m as usize];
        for &x in values {
            count[((x * m as f32) as usize).min(m as usize - 1)] += 1;
        }
        let lo = n / m;
        assert!(
            count.iter().all(|&c| c == lo || c == lo + 1),
            "{what}, base {b}: {m} strata, counts {count:?}"
        );
        assert_eq!(count.iter().sum::<u32>(), n);
    }

    /// Rotated Halton sets at powers of their bases put exactly one point per stratum.
    #[test]
    fn halton_sets_are_stratified_at_powers_of_their_bases() {
        let mut rng = PixelRng::new(9, 4);
        let mut pos = Vec::new();
        let mut t = Vec::new();
        for (n, dim) in [
            (16, Dimension::Pixel),
            (8, Dimension::Pixel),
            (49, Dimension::Lens),
        ] {
            for _ in 0..20 {
                fill_2d(SamplerKind::Halton, n, dim, false, &mut rng, &mut pos);
                let (bx, by) = dim.bases();
                let xs: Vec<f32> = pos.iter().map(|p| p.0).collect();
                let ys: Vec<f32> = pos.iter().map(|p| p.1).collect();
                assert_halton_strata(&xs, bx, &format!("{dim:?} {n}"));
                assert_halton_strata(&ys, by, &format!("{dim:?} {n}"));
            }
        }
        for n in [11, 121, 30] {
            for _ in 0..20 {
                fill_1d(SamplerKind::Halton, n, Dimension::Time, &mut rng, &mut t);
                assert_halton_strata(&t, 11, &format!("time {n}"));
            }
        }
    }

    #[test]
    fn every_pattern_stays_in_the_unit_square() {
        let mut rng = PixelRng::new(1, 2);
        let mut pos = Vec::new();
        let mut t = Vec::new();
        for &kind in SamplerKind::ALL {
            for n in [1u32, 2, 7, 16, 33] {
                fill_2d(kind, n, Dimension::Lens, false, &mut rng, &mut pos);
                assert_eq!(pos.len(), n as usize);
                assert!(
                    pos.iter()
                        .all(|&(x, y)| (0.0..1.0).contains(&x) && (0.0..1.0).contains(&y)),
                    "{kind} {n}"
                );
                fill_1d(kind, n, Dimension::Time, &mut rng, &mut t);
                assert_eq!(t.len(), n as usize);
                assert!(t.iter().all(|x| (0.0..1.0).contains(x)));
                if matches!(kind, SamplerKind::Grid | SamplerKind::Jittered) {
                    // grid and jittered put one value in each of n strata
                    let mut seen = vec![0; n as usize];
                    for x in &t {
                        seen[(x * n as f32) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "{kind} {n}: {t:?}");
                }
                if kind == SamplerKind::Halton {
                    // The time set is base 11, the lens set bases 5 and 7.
                    let xs: Vec<f32> = pos.iter().map(|p| p.0).collect();
                    let ys: Vec<f32> = pos.iter().map(|p| p.1).collect();
                    for (values, base) in [(&t, 11), (&xs, 5), (&ys, 7)] {
                        assert_halton_strata(values, base, &format!("{kind} {n}"));
                    }
                }
            }
        }
        assert_eq!(radical_inverse(2, 1), 0.5);
        assert_eq!(radical_inverse(2, 3), 0.75);
        assert!((radical_inverse(3, 5) - (2.0 / 3.0 + 1.0 / 9.0)).abs() < 1e-6);
    }

    #[test]
    fn filters() {
        assert_eq!(FilterKind::Box.weight(0.4, -0.3), 1.0);
        let g = FilterKind::Gaussian;
        assert!(g.weight(0.0, 0.0) > g.weight(0.5, 0.0));
        assert_eq!(g.weight(1.5, 0.1), 0.0);
        assert_eq!(
            "halton".parse::<SamplerKind>().unwrap(),
            SamplerKind::Halton
        );
        assert_eq!("sobol".parse::<SamplerKind>().unwrap(), SamplerKind::Sobol);
        assert!("owen".parse::<SamplerKind>().is_err());
        assert_eq!(
            "gaussian".parse::<FilterKind>().unwrap(),
            FilterKind::Gaussian
        );
    }

    /// `next_f32` (which leaves out `mix64`'s last step) is the top 24 bits of
    /// `next_u64` on the same stream, draw for draw, and `fill_f32` is `next_f32`.
    #[test]
    fn unit_draws_are_the_top_bits_of_the_full_mix() {
        for seed in 0..64u64 {
            let (mut a, mut b, mut c) = (
                PixelRng::new(seed, 9),
                PixelRng::new(seed, 9),
                PixelRng::new(seed, 9),
            );
            let mut filled = [0.0f32; 37];
            c.fill_f32(&mut filled);
            for f in filled {
                let x = a.next_f32();
                let y = (b.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32);
                assert_eq!(
                    (x.to_bits(), f.to_bits()),
                    (y.to_bits(), y.to_bits()),
                    "seed {seed}"
                );
            }
        }
    }

    #[test]
    fn pixel_streams_depend_on_seed_and_pixel_only() {
        let draw = |seed, pixel| {
            let mut r = PixelRng::new(seed, pixel);
            (0..4).map(|_| r.next_u64()).collect::<Vec<_>>()
        };
        assert_eq!(draw(1, 2), draw(1, 2));
        assert_ne!(draw(1, 2), draw(1, 3));
        assert_ne!(draw(1, 2), draw(2, 2));
        let mut r = PixelRng::new(0, 0);
        for _ in 0..10_000 {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            assert!(r.below(3) < 3);
        }
    }
}
