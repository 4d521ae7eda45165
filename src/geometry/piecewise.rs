//! Piecewise-constant distributions in one and two dimensions, sampled by inverting
//! their CDFs: pbrt-v4's `PiecewiseConstant1D` / `PiecewiseConstant2D` (Pharr, Jakob,
//! Humphreys, *Physically Based Rendering*, 4th ed., §A.4.2 and §A.5; 3rd ed. §13.6.7),
//! here over `[0, 1)` and `[0, 1)²`. The 2D one is a marginal distribution over rows
//! and one conditional distribution per row; it is what the environment map's
//! importance sampling uses (`scene::Environment`).
//!
//! Sums and CDFs are kept in `f64`: a 2048 x 1024 map has two million buckets, and an
//! `f32` running sum over that many loses the small ones.

/// A piecewise-constant density over `[0, 1)` with `n` equal buckets.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant1D {
    func: Vec<f64>,
    /// `cdf[0] = 0`, `cdf[n] = 1`, non-decreasing.
    cdf: Vec<f64>,
    /// `∫ func` over `[0, 1)` (the mean of `func`).
    integral: f64,
}

impl PiecewiseConstant1D {
    /// The distribution proportional to `func` (non-negative, finite, at least one
    /// entry). An all-zero `func` gives the uniform distribution with `integral() == 0`
    /// (pbrt's convention), so a caller must check the integral before sampling a
    /// function it wants to be proportional to.
    pub fn new(func: &[f64]) -> Self {
        assert!(!func.is_empty(), "a distribution needs at least one bucket");
        debug_assert!(func.iter().all(|f| f.is_finite() && *f >= 0.0));
        let n = func.len();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut sum = 0.0;
        for f in func {
            sum += f / n as f64;
            cdf.push(sum);
        }
        let integral = sum;
        if integral > 0.0 {
            for c in &mut cdf[1..] {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
        }
        cdf[n] = 1.0;
        PiecewiseConstant1D {
            func: func.to_vec(),
            cdf,
            integral,
        }
    }

    /// Number of buckets.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false: a distribution has at least one bucket.
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫₀¹ func(x) dx`.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// The density of bucket `i` (with respect to `x` in `[0, 1)`).
    pub fn pdf(&self, i: usize) -> f64 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// Maps `u` in `[0, 1)` to `(x, bucket)`, `x` in `[0, 1)` distributed as the
    /// density. The bucket is the last one whose CDF start is `<= u`, so a bucket of
    /// zero width is never returned.
    pub fn sample(&self, u: f64) -> (f64, usize) {
        let n = self.func.len();
        let u = u.clamp(0.0, 1.0);
        // Largest i with cdf[i] <= u, among 0..n.
        let i = (self.cdf.partition_point(|&c| c <= u) - 1).min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // Stay inside the bucket even when du rounds to 1.
        let x = ((i as f64 + du) / n as f64).min((i as f64 + 1.0 - 1e-9) / n as f64);
        (x, i)
    }
}

/// A piecewise-constant density over `[0, 1)²` on a `width x height` grid of buckets
/// (row-major, row `j` covering `v` in `[j / height, (j + 1) / height)`).
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant2D {
    conditional: Vec<PiecewiseConstant1D>,
    marginal: PiecewiseConstant1D,
}

impl PiecewiseConstant2D {
    /// The distribution proportional to `func` (`width * height` non-negative values).
    pub fn new(func: &[f64], width: usize, height: usize) -> Self {
        assert_eq!(func.len(), width * height, "one value per bucket");
        let conditional: Vec<_> = func.chunks(width).map(PiecewiseConstant1D::new).collect();
        let rows: Vec<f64> = conditional.iter().map(|c| c.integral()).collect();
        PiecewiseConstant2D {
            conditional,
            marginal: PiecewiseConstant1D::new(&rows),
        }
    }

    /// `∫∫ func du dv`.
    pub fn integral(&self) -> f64 {
        self.marginal.integral()
    }

    /// Maps `(u0, u1)` to `((u, v), (column, row))`: the row from the marginal with
    /// `u1`, the column from that row's conditional with `u0`.
    pub fn sample(&self, u0: f64, u1: f64) -> ((f64, f64), (usize, usize)) {
        let (v, row) = self.marginal.sample(u1);
        let (u, col) = self.conditional[row].sample(u0);
        ((u, v), (col, row))
    }

    /// The density at bucket `(column, row)` with respect to `(u, v)`.
    pub fn pdf(&self, col: usize, row: usize) -> f64 {
        let total = self.marginal.integral();
        if total > 0.0 {
            self.conditional[row].func[col] / total
        } else {
            1.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sampling inverts the CDF: equally spaced `u` land in each bucket in proportion
    /// to its weight, and a zero bucket is never chosen.
    #[test]
    fn one_dimensional_samples_follow_the_weights_and_skip_zero_buckets() {
        let d = PiecewiseConstant1D::new(&[1.0, 0.0, 3.0, 0.0]);
        assert_eq!(d.integral(), 1.0);
        assert_eq!(d.pdf(0), 1.0);
        assert_eq!(d.pdf(2), 3.0);
        let n = 4000;
        let mut counts = [0usize; 4];
        for k in 0..n {
            let (x, i) = d.sample((k as f64 + 0.5) / n as f64);
            assert!(
                (i as f64 / 4.0..(i as f64 + 1.0) / 4.0).contains(&x),
                "{x} {i}"
            );
            counts[i] += 1;
        }
        assert_eq!(counts, [1000, 0, 3000, 0]);
        // The boundary u = 1/4 is the start of bucket 2, not the empty bucket 1.
        assert_eq!(d.sample(0.25).1, 2);
        assert_eq!(d.sample(0.999_999_999).1, 2);
    }

    /// The 2D pdf integrates to 1 over `[0, 1)²` and equals `func / ∫func`.
    #[test]
    fn two_dimensional_pdf_is_normalised() {
        let func = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let d = PiecewiseConstant2D::new(&func, 3, 2);
        assert!((d.integral() - 15.0 / 6.0).abs() < 1e-12);
        let sum: f64 = (0..2)
            .flat_map(|r| (0..3).map(move |c| (c, r)))
            .map(|(c, r)| d.pdf(c, r) / 6.0)
            .sum();
        // Six terms of f64 rounding.
        assert!((sum - 1.0).abs() < 1e-12, "{sum}");
        let ((u, v), (c, r)) = d.sample(0.0, 0.0);
        assert_eq!((c, r), (1, 0), "bucket (0, 0) has zero weight");
        assert!(u >= 1.0 / 3.0 && v < 0.5);
    }
}
