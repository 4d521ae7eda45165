//! What a render did: rays by kind, time by phase. Counted per tile and summed, so
//! counting costs no atomics on the hot path.

use serde::Serialize;
use std::ops::AddAssign;

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RayCounts {
    pub camera: u64,
    pub shadow: u64,
    pub reflection: u64,
    pub refraction: u64,
    /// Rays sampled in a glossy reflection lobe.
    pub glossy: u64,
    /// Refracted rays sampled in a translucency lobe.
    pub translucency: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.camera
            + self.shadow
            + self.reflection
            + self.refraction
            + self.glossy
            + self.translucency
    }
}

/// Samples drawn for the distributed effects: lens points, shutter times, points on
/// area lights and glossy or translucent directions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct EffectSamplesDrawn {
    pub lens: u64,
    pub time: u64,
    pub light: u64,
    pub glossy: u64,
}

impl EffectSamplesDrawn {
    pub fn total(&self) -> u64 {
        self.lens + self.time + self.light + self.glossy
    }
}

impl AddAssign for EffectSamplesDrawn {
    fn add_assign(&mut self, o: Self) {
        self.lens += o.lens;
        self.time += o.time;
        self.light += o.light;
        self.glossy += o.glossy;
    }
}

impl AddAssign for RayCounts {
    fn add_assign(&mut self, o: Self) {
        self.camera += o.camera;
        self.shadow += o.shadow;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
        self.glossy += o.glossy;
        self.translucency += o.translucency;
    }
}

/// Wall-clock milliseconds per phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PhaseTimes {
    pub load: f64,
    pub build: f64,
    pub render: f64,
    pub write: f64,
}

impl PhaseTimes {
    pub fn total(&self) -> f64 {
        self.load + self.build + self.render + self.write
    }
}

/// Milliseconds elapsed since `start`.
pub fn ms_since(start: std::time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
