//! What the pixel filter accumulates for one pixel, kept exact so that the sums of
//! several renders of disjoint sample slices (`--sample-range`) merge into exactly the
//! sums of one render of all the samples.

use super::exact_sum::ExactSum;
use glam::Vec3;

/// The filter sums of one pixel over some of its eye samples: `Σ w·L` per channel,
/// `Σ w`, the unweighted `Σ L` (the fallback should every weight be zero) and the
/// number of eye samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelSums {
    pub weighted: [ExactSum; 3],
    pub weight: ExactSum,
    pub plain: [ExactSum; 3],
    pub samples: u32,
}

impl PixelSums {
    /// Adds one eye sample of filter weight `w` and (finite) radiance `l`. The product
    /// `w * l` is rounded to f32 here, per sample, so it does not depend on how the
    /// samples are split.
    #[inline]
    pub fn add_sample(&mut self, w: f32, l: Vec3) {
        let wl = w * l;
        for c in 0..3 {
            self.weighted[c].add(wl[c]);
            self.plain[c].add(l[c]);
        }
        self.weight.add(w);
        self.samples += 1;
    }

    /// Adds the sums of other samples of the same pixel.
    pub fn merge(&mut self, o: &PixelSums) {
        for c in 0..3 {
            self.weighted[c].add_sum(&o.weighted[c]);
            self.plain[c].add_sum(&o.plain[c]);
        }
        self.weight.add_sum(&o.weight);
        self.samples += o.samples;
    }

    /// The pixel value: `Σ w·L / Σ w` (a ratio estimator; the plain mean for the box
    /// filter, whose weights are all 1), or the plain mean `Σ L / n` should every sample
    /// have landed where the filter is zero; black for a pixel without samples. Divided
    /// in f64 and rounded once to f32.
    pub fn value(&self) -> Vec3 {
        let w = self.weight.to_f64();
        let (num, den) = if w > 0.0 {
            (&self.weighted, w)
        } else if self.samples > 0 {
            (&self.plain, self.samples as f64)
        } else {
            return Vec3::ZERO;
        };
        Vec3::new(
            (num[0].to_f64() / den) as f32,
            (num[1].to_f64() / den) as f32,
            (num[2].to_f64() / den) as f32,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_is_the_weighted_mean_and_merging_is_exact() {
        let samples = [
            (1.0, Vec3::new(1e8, 0.5, 0.0)),
            (0.25, Vec3::new(1.0, 0.25, 2.0)),
            (0.5, Vec3::new(-1e8, 0.75, 4.0)),
        ];
        let mut all = PixelSums::default();
        for &(w, l) in &samples {
            all.add_sample(w, l);
        }
        // Σ w L = (1e8 + 0.25 - 5e7, 0.5 + 0.0625 + 0.375, 0 + 0.5 + 2) over Σ w = 1.75.
        let expect = Vec3::new(
            ((1e8 + 0.25 - 5e7) / 1.75) as f32,
            (0.9375 / 1.75) as f32,
            (2.5 / 1.75) as f32,
        );
        assert_eq!(all.value(), expect);
        let (mut a, mut b) = (PixelSums::default(), PixelSums::default());
        a.add_sample(samples[2].0, samples[2].1);
        b.add_sample(samples[0].0, samples[0].1);
        b.add_sample(samples[1].0, samples[1].1);
        a.merge(&b);
        assert_eq!(
            a.value().to_array().map(f32::to_bits),
            all.value().to_array().map(f32::to_bits)
        );
        assert_eq!(a.samples, 3);
    }

    #[test]
    fn zero_weights_fall_back_to_the_plain_mean() {
        let mut p = PixelSums::default();
        assert_eq!(p.value(), Vec3::ZERO);
        p.add_sample(0.0, Vec3::new(1.0, 2.0, 3.0));
        p.add_sample(0.0, Vec3::new(3.0, 2.0, 1.0));
        assert_eq!(p.value(), Vec3::splat(2.0));
    }
}
