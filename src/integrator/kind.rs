//! Which integrator renders: the recursive reference or the wavefront.

use super::{RenderOptions, RenderOutput, recursive, sampling, wavefront};
use crate::error::{Error, Result};
use crate::film::Film;
use crate::scene::Scene;

/// Which integrator renders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum IntegratorKind {
    /// Recursive, depth first, one ray at a time: the reference.
    #[default]
    Whitted,
    /// Breadth first over ray queues, traced in packets.
    Wavefront,
}

impl IntegratorKind {
    pub const ALL: &'static [IntegratorKind] =
        &[IntegratorKind::Whitted, IntegratorKind::Wavefront];

    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Whitted => "whitted",
            IntegratorKind::Wavefront => "wavefront",
        }
    }

    /// Renders with this integrator.
    pub fn render(
        self,
        scene: &Scene,
        accel: &crate::accel::SceneAccel,
        opts: &RenderOptions,
    ) -> RenderOutput {
        match self {
            IntegratorKind::Whitted => recursive::render(scene, accel, opts),
            IntegratorKind::Wavefront => wavefront::render(scene, accel, opts),
        }
    }

    /// [`IntegratorKind::render`] into `film`, made before the render with its memory
    /// mapped ([`Film::committed`]); it must be the size of the region
    /// (`opts.region()`).
    pub fn render_into(
        self,
        scene: &Scene,
        accel: &crate::accel::SceneAccel,
        opts: &RenderOptions,
        film: Film,
    ) -> RenderOutput {
        match self {
            IntegratorKind::Whitted => recursive::render_with(scene, accel, opts, Some(film)),
            IntegratorKind::Wavefront => wavefront::render_with(scene, accel, opts, Some(film)),
        }
    }
}

impl std::str::FromStr for IntegratorKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        sampling::parse_named(IntegratorKind::ALL, IntegratorKind::name, "integrator", s)
    }
}

impl std::fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
