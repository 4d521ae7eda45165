//! How a measurement is timed and what a row of results holds.

use super::protocol::Checksums;
use serde::Serialize;

/// CPU share below which a measurement is repeated with `--retry-busy` (Embree's
/// harness uses the same).
pub const BUSY_SHARE: f64 = 0.98;

/// How each figure is timed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Timed passes per figure.
    pub reps: usize,
    /// Untimed passes run first until this many seconds have gone by (at least one).
    pub warmup_s: f64,
    /// Repeat a figure's warm-up and timed passes up to this many more times while the
    /// process got less than [`BUSY_SHARE`] of its cores, keeping the attempt with the
    /// highest share (Embree's harness: `--retry-busy`).
    pub retry_busy: usize,
}

impl Timing {
    /// `reps` timed passes after one warm-up pass, no retries.
    pub fn passes(reps: usize) -> Self {
        Timing {
            reps,
            warmup_s: 0.0,
            retry_busy: 0,
        }
    }
}

/// One timed figure.
#[derive(Clone, Debug)]
pub struct Measured {
    pub checksums: Checksums,
    /// Mrays/s of each timed pass.
    pub rates: Vec<f64>,
    /// Process CPU time over the timed passes / (their wall time x threads); NaN where
    /// there is no CPU clock.
    pub cpu_util: f64,
    /// Measurements made (more than one with `retry_busy`).
    pub attempts: usize,
}

/// One row of the report: the JSON fields of the issue, plus the instruction set.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub tracer: &'static str,
    pub mode: String,
    pub workload: &'static str,
    pub threads: usize,
    pub rays: u64,
    pub hits_or_occluded: u64,
    pub sum_t: f64,
    pub mrays_median: f64,
    pub mrays_min: f64,
    pub mrays_max: f64,
    pub build_ms: f64,
    pub isa: &'static str,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Process CPU time over the timed passes / (their wall time x threads): near 1.00
    /// when the figure had its cores to itself (null without a CPU clock).
    pub cpu_util: f64,
    /// Measurements made for the figure (more than one with `--retry-busy`).
    pub attempts: usize,
    pub build_ms_min: f64,
    pub build_ms_max: f64,
    /// Bytes of the traced structure (nodes and leaves) per triangle.
    pub bytes_per_triangle: f64,
}

/// Median of a non-empty list.
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}
