//! How far from a sphere's centre a shadow segment must stay for the sphere test
//! (`geometry::intersect_sphere`, which `kernels::sphere_lanes` repeats bit for bit) to
//! find no root on it: [`clearance`], a bound derived from the test's f32 operations
//! below, which the lane culls (`shadow_cull::sphere_clear` for point lights,
//! `integrator::tiny_shadow::sphere_clear_of` for quad lights) use as their margin, so
//! that skipping a sphere they call clear changes no answer.
//!
//! # The bound
//!
//! Rounding model (Higham, "Accuracy and Stability of Numerical Algorithms", §2-3;
//! pbrt-v4 §6.8 "Managing Rounding Error"): `fl(x op y) = (x op y)(1 + ε)`, `|ε| <= u =
//! 2^-24`, and `γ(n) = n u / (1 - n u)` bounds `n` such factors. The ray is `o + t d`,
//! `t` in `(0, tmax)` with `tmax <= 1` (`spawn_ray_to`), all fields f32; the sphere
//! `(c, r)`. Exact values: `f = o - c`, `F = |f|`, `a = d·d`, `b = -f·d`, `s = b/a`,
//! `l = f + s d` (the centre's foot on the line, `l ⊥ d`, `D = |l|`), `c0 = F² - r²`.
//! Computed values wear hats. The test computes `f̂, â, b̂, ŝ = fl(b̂/â), l̂ = fl(f̂ + ŝ
//! d)`, `disc = fl(â fl(r̂² - l̂·l̂))`, `ĉ = fl(f̂·f̂ - r̂²)`, `q̂ = fl(b̂ + copysign(√disc,
//! b̂))` and reports a root `t̂1 = fl(q̂/â)` or `t̂0 = fl(ĉ/q̂)` in `(0, tmax)`.
//!
//! 1. `|f̂ - f| <= u F` (each component is one rounded difference of exact floats: no
//!    dependence on the coordinates' magnitude), `â = a(1 ± γ3)`, `|b̂ - b| <= γ4 F|d|`,
//!    `|ŝ - s| |d| <= γ12 F`, and per component of `l̂` four more roundings:
//!    `|l̂ - l| <= γ17 F`.
//! 2. A root needs `disc >= 0`, so `λ = |l̂|` has `λ²(1 - γ3) <= r²(1 + u)`; with `w² =
//!    r̂² - l̂·l̂ >= 0`, `λ² + w² = r²(1 ± γ5)`.
//! 3. The two roots in reals of the computed coefficients, `T, T' = (b̂ ± √disc)/â`, lie
//!    at `(T - s)|d| = ±w + e`, `|e| <= γ12 F + γ8 w` (the square root halves the
//!    relative errors of `â` and `disc`). As `|o + t d - c|² = D² + ((t - s)|d|)²` and
//!    `|D - λ| <= γ17 F`, both points are within `E1 = γ14 r + γ29 F` of the sphere,
//!    from either side.
//! 4. `t̂1 = T(1 ± γ2)`: moving by `γ2 |T||d| <= γ2 (F + r + E1)`, `t̂1` is a point within
//!    `γ32 (F + r)` of the sphere.
//! 5. `t̂0 = ĉ/q̂` is the other root `T'` times `(ĉ/C)(1 ± γ2)`, `C = â T T' = (b̂² -
//!    disc)/â`: `ĉ` and `C` are two evaluations of `c0 = b²/a + D² - r²`, `|ĉ - c0| <=
//!    γ6 (F² + r²)` and `|C - c0| <= γ50 (F² + r²)` (from 1-3), so `|ĉ - C| <= Δ =
//!    γ56 (F² + r²)`. Here the root can move far: `c0` cancels where the origin is near
//!    the sphere. The premise bounds it: say every point of the segment, the origin
//!    included, is farther than `r + m` from `c`, `m >= γ2048 (F + r)`. Then
//!    `c0 > m (F + r) > 2Δ`, so `ĉ, C > 0`, `t̂0` has the sign of `T'`, and
//!    `|t̂0/T' - 1| <= ρ = 3Δ/c0 + γ2`. A hit needs `T' > 0`, so `T' > tmax` (the point
//!    `T'` is within `E1 < m` of
//!    the sphere, so not on the segment), and `t̂0 < tmax`: the along-ray gap `G = (T' -
//!    tmax)|d|` below `ρ x`, `x = T'|d|`. With `φ(z) = |p(T') - z d/|d||² - |p(T')|²`
//!    (convex, `φ(0) = 0`), the end has `φ(G) >= (m - E1)(2r + m + E1) >= m(2r + m)/2`.
//!    - `F >= 2r`: `φ(G) <= G² + 2G(r + E1)` gives `G >= m/4`, and `ρ x <= γ283 (F + r)`
//!      (`3Δ/c0 <= 5 γ56`, `x <= F + r + E1`): no hit for `m >= γ1132 (F + r)`.
//!    - `F < 2r`: convexity gives `G/x >= φ(G)/φ(x)`, `φ(x) <= c0 + 2r E1 <= 2 c0`, so
//!      `G/x >= m r/(2 c0)`, and `ρ <= G/x` where `3Δ + γ2 c0 <= γ848 r² <= m r/2`: no
//!      hit for `m >= γ1696 r`.
//!
//! So: if every point of the segment lies farther than `r + E` from the centre, `E =
//! γ2048 (F + r)`, the test reports no root on it (neither `t̂0` nor `t̂1`, whichever it
//! picks). A cull then needs a lower bound on that distance for every segment of the
//! group, from how the segments are built (their origins and ends, and the rounding of
//! `d = fl(end - o)`, which moves `o + d` by at most `u |end - o|`): the callers' part.
//!
//! Range (what the model needs): no overflow (`F + r + |d| <= 2^30`, so every product
//! of four such lengths stays below 2^120), and no underflow that matters: `E |d| >=
//! 2^-40` keeps `|disc| >= |d|² m r` far from rounding to a zero (a `-0.0` would pass
//! as a real tangent root), and a subnormal partial product then moves a sum by at most
//! `2^-149`, far below `u F |d|`; a radius whose square is subnormal acts as one at
//! most `2^-70` larger. Outside that range [`clearance`] says nothing is clear.
//!
//! The constants are loose (`γ2048 ≈ 1.2e-4` relative; the test's real root error is
//! a few dozen roundings): what the adversarial tests check is that no case passes
//! the cull and is hit, and the shipped scenes' spheres are far from their segments.
//! The culls compute their distances in f64 from the f32 inputs, with `2^-40` of the
//! magnitudes involved added for their own rounding (f64 has `2^-53`).

/// `u = 2^-24`, the f32 unit roundoff, in f64.
const U: f64 = 1.0 / (1u64 << 24) as f64;

/// `γ(n) = n u / (1 - n u)` in f64.
pub const fn gamma64(n: f64) -> f64 {
    n * U / (1.0 - n * U)
}

/// The relative part of the bound: a root of the sphere test lies within
/// `ROOT_ERROR (F + r)` of the sphere (see the module).
pub const ROOT_ERROR: f64 = gamma64(2048.0);

/// The cull's own f64 rounding, relative to the magnitudes it works on.
pub const F64_SLACK: f64 = 1.0 / (1u64 << 40) as f64;

/// The distance every point of every segment of a group must keep from the centre of
/// the sphere `(_, radius)` for the sphere test to find no root on any of them:
/// `|radius| + E + slack`, `E = γ2048 (far + |radius|)` (see the module). `far` bounds
/// every segment's origin's distance from the centre; `slack` how far a segment's
/// points may lie from the region the caller measures the distance to; `shortest` and
/// `longest` bound every `|d|` from below and above. `None` (nothing is clear) for
/// non-finite or out-of-range inputs.
pub fn clearance(radius: f32, far: f64, slack: f64, shortest: f64, longest: f64) -> Option<f64> {
    // A radius whose square underflows acts as one at most 2^-70 larger.
    let r = radius.abs() as f64 + 1.0 / (1u128 << 70) as f64;
    let e = ROOT_ERROR * (far + r);
    let fits = far + r + longest <= (1u64 << 30) as f64;
    let resolved = e * shortest >= 1.0 / (1u64 << 40) as f64;
    let need = r + e + slack;
    (need.is_finite() && fits && resolved && slack >= 0.0).then_some(need)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound is what the module says, and refuses what it should.
    #[test]
    fn clearance_is_radius_plus_root_error_plus_slack() {
        let need = clearance(-2.0, 10.0, 0.5, 1.0, 20.0).expect("in range");
        let r = 2.0 + 1.0 / (1u128 << 70) as f64;
        assert_eq!(need, r + ROOT_ERROR * (10.0 + r) + 0.5);
        const { assert!(ROOT_ERROR > 1.2e-4 && ROOT_ERROR < 1.23e-4) };
        assert_eq!(clearance(f32::NAN, 10.0, 0.5, 1.0, 20.0), None);
        assert_eq!(clearance(f32::INFINITY, 10.0, 0.5, 1.0, 20.0), None);
        assert_eq!(clearance(1.0, f64::NAN, 0.5, 1.0, 20.0), None);
        assert_eq!(clearance(1.0, 10.0, f64::NAN, 1.0, 20.0), None);
        assert_eq!(clearance(1.0, 10.0, 0.5, f64::NAN, 20.0), None);
        assert_eq!(clearance(1.0, 10.0, 0.5, 1.0, 2e9), None);
        // Segments too short for the bound's range.
        assert_eq!(clearance(1e-3, 1e-3, 0.0, 1e-12, 1.0), None);
    }
}
