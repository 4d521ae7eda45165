//! sRGB encoding and luminance of linear RGB.

use glam::Vec3;

/// Relative luminance of linear Rec. 709 / sRGB primaries (ITU-R BT.709 weights).
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// sRGB OETF (IEC 61966-2-1): linear segment below 0.0031308, power 1/2.4 above.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`linear_to_srgb`].
pub fn srgb_to_linear(s: f32) -> f32 {
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// One channel to an 8-bit sRGB code: clamp, encode, round. NaN becomes 0 rather
/// than whatever a float-to-int cast would make of it.
pub fn linear_to_srgb8(c: f32) -> u8 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (linear_to_srgb(c) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints_and_round_trip() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(-3.0), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        // 18% grey is code 118 in sRGB, not the 0.18 * 255 = 46 of a linear encoding.
        assert_eq!(linear_to_srgb8(0.18), 118);
        for code in 0..=255u8 {
            let lin = srgb_to_linear(code as f32 / 255.0);
            assert_eq!(
                linear_to_srgb8(lin),
                code,
                "code {code} does not round-trip"
            );
        }
        // The two branches meet: the OETF is continuous at the threshold.
        let t = 0.003_130_8f32;
        assert!((12.92 * t - (1.055 * t.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
    }
}
