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
    /// Shadow rays the plain occlusion query found blocked and that were traced again
    /// through transmissive surfaces (transmitted shadows, `integrator::shadow`).
    pub transmitted_shadow: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.camera
            + self.shadow
            + self.reflection
            + self.refraction
            + self.glossy
            + self.translucency
            + self.transmitted_shadow
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
    /// Directions drawn towards the environment.
    pub environment: u64,
}

impl EffectSamplesDrawn {
    pub fn total(&self) -> u64 {
        self.lens + self.time + self.light + self.glossy + self.environment
    }
}

impl AddAssign for EffectSamplesDrawn {
    fn add_assign(&mut self, o: Self) {
        self.lens += o.lens;
        self.time += o.time;
        self.light += o.light;
        self.glossy += o.glossy;
        self.environment += o.environment;
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
        self.transmitted_shadow += o.transmitted_shadow;
    }
}

/// Milliseconds spent in each stage of the wavefront integrator, summed over worker
/// threads (so on `n` threads they add up to about `n` times the render time, less the
/// time threads wait for work). A stage the scene does not need does not exist and is
/// `None` (absent from the JSON); the recursive integrator has no stages.
///
/// `setup` and `assemble` are the serial work of the render phase, before the first
/// tile and after the last (one thread works, the others wait), so on `n` threads
/// `n * render - sum of the stages` is about the time threads spent waiting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StageTimes {
    /// Before the tiles: the camera, the film, the per-worker scratch slots (serial).
    pub setup: f64,
    /// Camera-ray generation.
    pub camera: f64,
    /// Closest hits of camera rays.
    pub trace: f64,
    /// Shading of every hit, emitting shadow and child rays into their queues. In a
    /// tiny scene it also settles the shadow rays of point, directional and quad lights
    /// (`integrator::point_shadow`, `integrator::area_light`), which then leave
    /// `shadow` and `area_shadow` at zero.
    pub shade: f64,
    /// Occlusion of shadow rays towards point and directional lights (queued ones).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shadow: Option<f64>,
    /// Occlusion of shadow rays towards points on area lights.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub area_shadow: Option<f64>,
    /// Closest hits of the secondary queues, one stage per queue.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reflection: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refraction: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub glossy: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translucency: Option<f64>,
    /// The pixel filter (camera-sample radiance into pixel values and sums) and the
    /// copy of each finished tile into the film.
    pub resolve: f64,
    /// Mapping the film's fresh pages, band by band before its tiles are written
    /// (`film::populate_for_writing`): the kernel's (and on a VM, the host's) first
    /// touch of memory, apart from the renderer's own work.
    pub film: f64,
    /// After the tiles: the bands' counts and sums merged, the scratch freed (serial).
    pub assemble: f64,
}

impl StageTimes {
    /// Closest hits of all secondary queues together.
    pub fn secondary(&self) -> f64 {
        [
            self.reflection,
            self.refraction,
            self.glossy,
            self.translucency,
        ]
        .iter()
        .flatten()
        .sum()
    }
}

impl AddAssign for StageTimes {
    fn add_assign(&mut self, o: Self) {
        fn add(a: &mut Option<f64>, b: Option<f64>) {
            if let Some(b) = b {
                *a = Some(a.unwrap_or(0.0) + b);
            }
        }
        self.setup += o.setup;
        self.camera += o.camera;
        self.trace += o.trace;
        self.shade += o.shade;
        add(&mut self.shadow, o.shadow);
        add(&mut self.area_shadow, o.area_shadow);
        add(&mut self.reflection, o.reflection);
        add(&mut self.refraction, o.refraction);
        add(&mut self.glossy, o.glossy);
        add(&mut self.translucency, o.translucency);
        self.resolve += o.resolve;
        self.film += o.film;
        self.assemble += o.assemble;
    }
}

/// Wall-clock milliseconds per phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PhaseTimes {
    pub load: f64,
    /// The film's memory taken and mapped before any work (`Film::committed`).
    pub film: f64,
    pub build: f64,
    pub render: f64,
    pub write: f64,
}

impl PhaseTimes {
    pub fn total(&self) -> f64 {
        self.load + self.film + self.build + self.render + self.write
    }
}

/// Page faults per phase (minor and major, the whole process): how much fresh memory
/// each phase mapped. On a virtual machine a fresh page can cost tens of microseconds
/// (the host backs it on first touch), so a phase whose time moves between runs while
/// its work does not often shows it here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct PhaseFaults {
    pub load: u64,
    pub film: u64,
    pub build: u64,
    pub render: u64,
    pub write: u64,
}

/// Page faults (minor and major) taken so far by the whole process, all threads; zero
/// where the platform does not count them.
pub fn process_page_faults() -> u64 {
    #[cfg(unix)]
    {
        // SAFETY: `getrusage` writes one `rusage` through the valid pointer; all-zero
        // is a valid `rusage`.
        let mut r: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut r) } == 0 {
            return (r.ru_minflt + r.ru_majflt) as u64;
        }
    }
    0
}

/// Milliseconds elapsed since `start`.
pub fn ms_since(start: std::time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
