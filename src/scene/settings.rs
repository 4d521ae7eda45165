//! Render defaults and per-effect sample counts a scene file may set.

/// Render defaults a scene file may set; the command line overrides them.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Paths whose throughput falls below this stop (the contribution cutoff).
    pub min_contribution: f32,
    /// Samples per effect besides the eye (pixel) samples, which are `spp`.
    pub samples: SampleCounts,
    /// Shadow rays pass through transmissive (glass) surfaces, attenuated by each
    /// surface's `transmission` (POV-Ray's default: filtered light, no caustics, no
    /// bending). Off: every surface blocks light. Default on; see
    /// `integrator::shadow` for why.
    pub transmitted_shadows: bool,
}

/// How many samples each distributed effect takes (Cook, Porter, Carpenter 1984). The
/// eye (pixel) count is `spp`; these multiply it:
///
/// - `lens`, `time`: camera rays per pixel = `spp * lens * time`. Each eye sample
///   carries `lens` lens points and each of those `time` shutter times; the lens points
///   of a pixel form one stratified set of size `spp * lens`, shuffled against the
///   pixel positions, and the times one set of size `spp * lens * time`, so that eye
///   samples alone already stratify the lens and the shutter.
/// - `shadow`: stratified points per area light at every shading point (point and
///   directional lights always take one shadow ray).
/// - `glossy`: rays per glossy or translucent lobe at the first hit of a camera ray;
///   deeper hits take one, which keeps the ray tree from growing exponentially.
/// - `environment`: directions drawn towards the environment (a shadow ray to
///   infinity each) at every lit shading point, as `shadow` is for each area light.
///
/// A count applies only when the scene has the effect: in a scene without depth of
/// field `lens` is ignored, and so on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct SampleCounts {
    pub shadow: u32,
    pub glossy: u32,
    pub lens: u32,
    pub time: u32,
    pub environment: u32,
}

impl Default for SampleCounts {
    fn default() -> Self {
        SampleCounts {
            shadow: 1,
            glossy: 1,
            lens: 1,
            time: 1,
            environment: 1,
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            spp: 1,
            max_depth: 8,
            min_contribution: 1e-3,
            samples: SampleCounts::default(),
            transmitted_shadows: true,
        }
    }
}
