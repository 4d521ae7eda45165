//! Which structure to build ([`AccelKind`]), by name on the command line.

use super::{Accel, BruteForce, Bvh2, Bvh4, Bvh4c, Bvh8, Bvh8c, Grid, KdTree, Octree, Primitives};
use crate::error::{Error, Result};
use std::str::FromStr;

/// Which structure to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccelKind {
    BruteForce,
    Bvh2,
    Bvh4,
    Bvh8,
    /// The BVH4 with compressed (quantised) nodes.
    Bvh4c,
    /// The BVH8 with compressed (quantised) nodes.
    Bvh8c,
    Grid,
    Octree,
    KdTree,
}

impl AccelKind {
    pub const ALL: &'static [AccelKind] = &[
        AccelKind::BruteForce,
        AccelKind::Bvh2,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Bvh4c,
        AccelKind::Bvh8c,
        AccelKind::Grid,
        AccelKind::Octree,
        AccelKind::KdTree,
    ];

    pub fn name(self) -> &'static str {
        match self {
            AccelKind::BruteForce => "bruteforce",
            AccelKind::Bvh2 => "bvh2",
            AccelKind::Bvh4 => "bvh4",
            AccelKind::Bvh8 => "bvh8",
            AccelKind::Bvh4c => "bvh4c",
            AccelKind::Bvh8c => "bvh8c",
            AccelKind::Grid => "grid",
            AccelKind::Octree => "octree",
            AccelKind::KdTree => "kdtree",
        }
    }

    /// Builds this structure over a primitive set.
    pub fn build<P: Primitives + 'static>(self, prims: P) -> Box<dyn Accel> {
        match self {
            AccelKind::BruteForce => Box::new(BruteForce::new(prims)),
            AccelKind::Bvh2 => Box::new(Bvh2::build(prims)),
            AccelKind::Bvh4 => Box::new(Bvh4::build(prims)),
            AccelKind::Bvh8 => Box::new(Bvh8::build(prims)),
            AccelKind::Bvh4c => Box::new(Bvh4c::build(prims)),
            AccelKind::Bvh8c => Box::new(Bvh8c::build(prims)),
            AccelKind::Grid => Box::new(Grid::build(prims)),
            AccelKind::Octree => Box::new(Octree::build(prims)),
            AccelKind::KdTree => Box::new(KdTree::build(prims)),
        }
    }
}

impl FromStr for AccelKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        AccelKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = AccelKind::ALL.iter().map(|k| k.name()).collect();
                Error::parameter(
                    "accel",
                    format!(
                        "unknown structure '{s}', expected one of {}",
                        names.join(", ")
                    ),
                )
            })
    }
}

impl std::fmt::Display for AccelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
