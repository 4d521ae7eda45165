//! Limits on render parameters (image size, samples per pixel, depth, per-effect
//! sample counts) and the checks that enforce them. Here, below the integrators,
//! because both the scene loader (which reports a bad value with its location) and
//! the render options check against them.

use super::SampleCounts;
use crate::error::{Error, Result};

/// Largest image side accepted (a 64k x 64k RGB f32 film is already 48 GiB).
pub const MAX_IMAGE_SIDE: u32 = 65_536;
/// Largest sample count per pixel accepted.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest recursion depth accepted.
pub const MAX_DEPTH: u32 = 64;
/// Largest per-effect sample count (shadow, glossy, lens, time) accepted.
pub const MAX_EFFECT_SAMPLES: u32 = 1024;

/// Rejects per-effect sample counts outside `1..=MAX_EFFECT_SAMPLES`.
pub fn validate_sample_counts(c: &SampleCounts) -> Result<()> {
    for (name, n) in [
        ("shadow", c.shadow),
        ("glossy", c.glossy),
        ("lens", c.lens),
        ("time", c.time),
    ] {
        if n == 0 || n > MAX_EFFECT_SAMPLES {
            return Err(Error::parameter(
                "sample count",
                format!("{name} = {n}: must be between 1 and {MAX_EFFECT_SAMPLES}"),
            ));
        }
    }
    Ok(())
}

/// Rejects absurd render parameters with a message saying what is allowed.
pub fn validate_dimensions(width: u32, height: u32, spp: u32, max_depth: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(Error::parameter(
            "image size",
            format!("{width}x{height}: width and height must be between 1 and {MAX_IMAGE_SIDE}"),
        ));
    }
    if (width as u64) * (height as u64) > 1 << 30 {
        return Err(Error::parameter(
            "image size",
            format!("{width}x{height} exceeds 2^30 pixels"),
        ));
    }
    if spp == 0 || spp > MAX_SPP {
        return Err(Error::parameter(
            "spp",
            format!("{spp}: samples per pixel must be between 1 and {MAX_SPP}"),
        ));
    }
    if max_depth > MAX_DEPTH {
        return Err(Error::parameter(
            "max depth",
            format!("{max_depth}: must be at most {MAX_DEPTH}"),
        ));
    }
    Ok(())
}
