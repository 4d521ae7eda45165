//! Display transform for 8-bit output: exposure in stops, then a tone-mapping operator,
//! then the sRGB OETF. Float outputs (HDR, EXR) never go through it: they keep the
//! linear radiance the integrator computed.

use super::color::Srgb8Table;
use super::linear_to_srgb8;
use crate::error::{Error, Result};
use std::str::FromStr;

/// Tone-mapping operator: linear radiance (after exposure) to display-linear [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToneMap {
    /// Clip each channel to [0, 1] (the historical behaviour, and the default).
    #[default]
    Clamp,
    /// Reinhard's global operator per channel, `c / (1 + c)` (Reinhard, Stark, Shirley
    /// and Ferwerda, "Photographic Tone Reproduction for Digital Images", SIGGRAPH 2002,
    /// eq. 3 without the white point): 1 maps to 1/2, nothing clips.
    Reinhard,
    /// ACES-like filmic curve per channel: Narkowicz's rational fit of the ACES
    /// reference rendering transform ("ACES Filmic Tone Mapping Curve", 2016),
    /// `x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14)`, clamped to [0, 1]. A toe darkens
    /// the shadows and a shoulder rolls off the highlights (saturates near x = 7.2).
    Filmic,
}

/// Names accepted by `--tonemap`, in [`ToneMap`] order.
pub const TONEMAP_NAMES: &[&str] = &["clamp", "reinhard", "filmic"];

impl FromStr for ToneMap {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "clamp" => Ok(ToneMap::Clamp),
            "reinhard" => Ok(ToneMap::Reinhard),
            "filmic" | "aces" => Ok(ToneMap::Filmic),
            _ => Err(format!(
                "unknown tone mapping `{s}`, expected one of {}",
                TONEMAP_NAMES.join(", ")
            )),
        }
    }
}

impl ToneMap {
    /// Maps one linear channel to display-linear. Negative values give 0; `+inf` gives
    /// 1 (Reinhard and filmic would otherwise compute inf/inf); NaN stays NaN, which
    /// [`linear_to_srgb8`] turns into code 0.
    pub fn apply(self, c: f32) -> f32 {
        match self {
            ToneMap::Clamp => c,
            ToneMap::Reinhard | ToneMap::Filmic if c == f32::INFINITY => 1.0,
            ToneMap::Reinhard => {
                let c = c.max(0.0);
                c / (1.0 + c)
            }
            ToneMap::Filmic => {
                let x = c.max(0.0);
                let y = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
                y.min(1.0)
            }
        }
    }
}

/// How an image file is written beyond the radiance itself.
///
/// Exposure and tone mapping apply to PNG only; HDR and EXR always hold the linear
/// radiance unchanged. `exr_half` selects 16-bit half floats in EXR output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageOptions {
    /// Exposure in stops: radiance is multiplied by `2^exposure` before tone mapping.
    pub exposure: f32,
    /// Tone-mapping operator for 8-bit output.
    pub tonemap: ToneMap,
    /// Write EXR channels as 16-bit half floats instead of 32-bit floats.
    pub exr_half: bool,
    /// Add depth, normal and albedo layers to an EXR output (a render job computes
    /// them, [`crate::integrator::aov`]); only EXR can hold them.
    pub aovs: bool,
}

/// Largest exposure magnitude accepted: 2^±64 already spans more than f32 radiance
/// needs; beyond, the scale itself overflows to inf or underflows to 0.
pub const MAX_EXPOSURE_STOPS: f32 = 64.0;

impl ImageOptions {
    /// Checks the options: the exposure must be finite and at most
    /// [`MAX_EXPOSURE_STOPS`] in magnitude.
    pub fn validate(&self) -> Result<()> {
        if !self.exposure.is_finite() || self.exposure.abs() > MAX_EXPOSURE_STOPS {
            return Err(Error::parameter(
                "exposure",
                format!(
                    "{} stops: expected a finite number in [-{MAX_EXPOSURE_STOPS}, {MAX_EXPOSURE_STOPS}]",
                    self.exposure
                ),
            ));
        }
        Ok(())
    }

    /// One linear channel to its 8-bit sRGB code: exposure, tone mapping, OETF. With
    /// the defaults (0 stops, clamp) it equals [`linear_to_srgb8`] exactly: `2^0` is 1.
    pub fn display8(&self, c: f32) -> u8 {
        linear_to_srgb8(self.tonemap.apply(c * self.exposure.exp2()))
    }
}

/// [`ImageOptions::display8`] for a whole image: `2^exposure` computed once and the
/// OETF by its code thresholds ([`Srgb8Table`]); the same codes.
#[derive(Clone, Debug)]
pub struct Display8 {
    scale: f32,
    tonemap: ToneMap,
    table: Srgb8Table,
}

impl Display8 {
    pub fn new(opts: &ImageOptions) -> Self {
        Display8 {
            scale: opts.exposure.exp2(),
            tonemap: opts.tonemap,
            table: Srgb8Table::new(),
        }
    }

    /// The code of one linear channel: [`ImageOptions::display8`]`(c)`.
    #[inline]
    pub fn code(&self, c: f32) -> u8 {
        self.table.encode(self.tonemap.apply(c * self.scale))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(exposure: f32, tonemap: ToneMap) -> ImageOptions {
        ImageOptions {
            exposure,
            tonemap,
            ..ImageOptions::default()
        }
    }

    // Expected codes computed by hand (f64): sRGB OETF of the operator's output, * 255,
    // rounded. Every value chosen lies at least 0.1 from a rounding boundary, far above
    // the ~1e-5 difference between f32 and f64 evaluation.
    /// `Display8`, the whole-image encoder, gives `display8`'s code under every
    /// operator and exposure, on radiance from 0 to 2^20 and the special values.
    #[test]
    fn whole_image_codes_are_display8() {
        let mut values: Vec<f32> = (0..200_000).map(|i| (i as f32 * 1e-4).powi(3)).collect();
        values.extend([-1.0, -0.0, f32::NAN, f32::INFINITY, f32::MAX, 1e-30]);
        for tonemap in [ToneMap::Clamp, ToneMap::Reinhard, ToneMap::Filmic] {
            for exposure in [-3.5, 0.0, 1.0, 2.25] {
                let o = opts(exposure, tonemap);
                let d = Display8::new(&o);
                for &c in &values {
                    assert_eq!(d.code(c), o.display8(c), "{tonemap:?} {exposure} {c:e}");
                }
            }
        }
    }

    #[test]
    fn known_radiance_gives_known_code_under_each_operator() {
        // Clamp: 0.18 -> 117.65 -> 118; 1 and above -> 255.
        assert_eq!(opts(0.0, ToneMap::Clamp).display8(0.18), 118);
        assert_eq!(opts(0.0, ToneMap::Clamp).display8(3.0), 255);
        // Reinhard: 3 -> 0.75 -> 224.61 -> 225; 0.25 -> 0.2 -> 123.55 -> 124.
        assert_eq!(opts(0.0, ToneMap::Reinhard).display8(3.0), 225);
        assert_eq!(opts(0.0, ToneMap::Reinhard).display8(0.25), 124);
        // Filmic: 1 -> 2.54/3.16 = 0.80380 -> 231.60 -> 232; 0.18 -> 0.26690 -> 141.13.
        assert_eq!(opts(0.0, ToneMap::Filmic).display8(1.0), 232);
        assert_eq!(opts(0.0, ToneMap::Filmic).display8(0.18), 141);
        // Filmic's shoulder passes 1 near x = 7.24 and is clamped there.
        assert_eq!(opts(0.0, ToneMap::Filmic).display8(10.0), 255);
    }

    #[test]
    fn exposure_scales_by_powers_of_two_before_the_operator() {
        // +2 stops: 0.045 * 4 = 0.18 exactly in f32 (a power-of-two scale).
        assert_eq!(opts(2.0, ToneMap::Clamp).display8(0.045), 118);
        assert_eq!(opts(2.0, ToneMap::Reinhard).display8(0.75), 225);
        assert_eq!(opts(-1.0, ToneMap::Filmic).display8(2.0), 232);
        // Without exposure, 0.75 under Reinhard is 0.4286 -> 175.4, not 225.
        assert_eq!(opts(0.0, ToneMap::Reinhard).display8(0.75), 175);
    }

    #[test]
    fn defaults_equal_the_plain_srgb_encoding_and_odd_values_are_safe() {
        let d = ImageOptions::default();
        for c in [
            -1.0,
            0.0,
            1e-4,
            0.003_130_8,
            0.5,
            1.0,
            2.0,
            f32::INFINITY,
            f32::NAN,
        ] {
            assert_eq!(d.display8(c), linear_to_srgb8(c), "{c}");
        }
        for t in [ToneMap::Reinhard, ToneMap::Filmic] {
            assert_eq!(opts(0.0, t).display8(f32::INFINITY), 255);
            assert_eq!(opts(0.0, t).display8(f32::NAN), 0);
            assert_eq!(opts(0.0, t).display8(-5.0), 0);
        }
    }

    #[test]
    fn bad_exposure_and_names_are_errors() {
        for e in [f32::NAN, f32::INFINITY, 65.0, -100.0] {
            assert!(opts(e, ToneMap::Clamp).validate().is_err(), "{e}");
        }
        assert!(opts(-64.0, ToneMap::Clamp).validate().is_ok());
        assert_eq!("Reinhard".parse::<ToneMap>(), Ok(ToneMap::Reinhard));
        assert_eq!("aces".parse::<ToneMap>(), Ok(ToneMap::Filmic));
        let err = "gamma".parse::<ToneMap>().unwrap_err();
        assert!(err.contains("clamp, reinhard, filmic"), "{err}");
    }
}
