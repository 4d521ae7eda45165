//! Running the protocol: every workload for one mode, and the whole `bench` command.

use super::modes::{
    COMPRESSED_MODES, MODES, PACKET_TUNING_MODES, SLAB_MODES, SORTED_MODES, TraceMode, build_mode,
    known_mode,
};
use super::protocol::Protocol;
use super::timing::{BenchRow, Timing, median};
use super::workload::Workload;
use crate::accel::Triangles;
use crate::simd::instruction_set;
use glam::Vec3;
use std::time::Instant;

/// Runs every workload for one mode at one thread count (inside the caller's pool):
/// `reps` timed passes after one warm-up pass, the build time as given.
pub fn run_mode(
    protocol: &Protocol,
    mode: &dyn TraceMode,
    threads: usize,
    reps: usize,
    build_ms: f64,
) -> Vec<BenchRow> {
    run_mode_timed(protocol, mode, threads, &Timing::passes(reps), &[build_ms])
}

/// Runs every workload for one mode at one thread count (inside the caller's pool),
/// timed as `timing` says; `builds` are the build times measured (ms, at least one).
pub fn run_mode_timed(
    protocol: &Protocol,
    mode: &dyn TraceMode,
    threads: usize,
    timing: &Timing,
    builds: &[f64],
) -> Vec<BenchRow> {
    let primary = protocol.primary_hits(mode);
    let triangles = protocol.tris.v0.len();
    Workload::ALL
        .iter()
        .map(|&w| {
            let p = (w != Workload::Primary).then_some(&primary);
            let m = protocol.measure(mode, w, p, timing);
            let c = m.checksums;
            BenchRow {
                tracer: "packet-render",
                mode: mode.name().to_string(),
                workload: w.name(),
                threads,
                rays: c.rays,
                hits_or_occluded: c.hits_or_occluded,
                sum_t: c.sum_t,
                mrays_median: median(&m.rates),
                mrays_min: m.rates.iter().copied().fold(f64::INFINITY, f64::min),
                mrays_max: m.rates.iter().copied().fold(0.0, f64::max),
                build_ms: median(builds),
                isa: instruction_set(),
                triangles,
                cpu_util: m.cpu_util,
                attempts: m.attempts,
                build_ms_min: builds.iter().copied().fold(f64::INFINITY, f64::min),
                build_ms_max: builds.iter().copied().fold(0.0, f64::max),
                bytes_per_triangle: mode.memory_bytes() as f64 / triangles.max(1) as f64,
            }
        })
        .collect()
}

/// The mesh a benchmark runs on: its name, every vertex (for the framing) and its
/// triangles in file order.
pub struct BenchMesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub triangles: Triangles,
}

/// Triangles of the default procedural mesh: Bunny-scale (the Stanford Bunny has 69,451).
pub const DEFAULT_MESH_TRIANGLES: usize = 69_451;

impl BenchMesh {
    /// An OBJ file (polygons split as fans, as the protocol says).
    pub fn from_obj(path: &std::path::Path) -> crate::Result<Self> {
        let obj = crate::scene::load::load_obj(path)?;
        let corners: Vec<[Vec3; 3]> = obj
            .indices
            .iter()
            .map(|t| {
                [
                    obj.positions[t[0] as usize],
                    obj.positions[t[1] as usize],
                    obj.positions[t[2] as usize],
                ]
            })
            .collect();
        Ok(BenchMesh {
            name: path.display().to_string(),
            positions: obj.positions,
            triangles: Triangles::from_corners(&corners),
        })
    }

    /// The procedural Bunny-scale mesh (`scene::procedural::tessellated_mesh`).
    pub fn procedural(triangles: usize) -> Self {
        let mut b = crate::scene::SceneBuilder::new();
        let m = b.add_material(crate::scene::Material::default());
        crate::scene::procedural::tessellated_mesh(&mut b, triangles, Vec3::ZERO, 1.0, m);
        let mesh = &b.mesh;
        let positions = (0..mesh.vertex_count() as u32)
            .map(|i| mesh.vertex(i))
            .collect();
        let corners: Vec<[Vec3; 3]> = (0..mesh.len()).map(|t| mesh.corners(t)).collect();
        BenchMesh {
            name: format!("procedural tessellated mesh ({} triangles)", corners.len()),
            positions,
            triangles: Triangles::from_corners(&corners),
        }
    }
}

/// Settings of a benchmark run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub modes: Vec<String>,
    /// Thread counts; 0 means all cores.
    pub threads: Vec<usize>,
    pub reps: usize,
    pub width: u32,
    pub height: u32,
    /// Warm-up seconds per figure (see [`Timing`]).
    pub warmup_s: f64,
    /// Retries of a figure measured while other load took cores (see [`Timing`]).
    pub retry_busy: usize,
}

/// Runs every mode at every thread count. `report` receives each row as it is measured.
pub fn run(
    mesh: &BenchMesh,
    opts: &BenchOptions,
    mut report: impl FnMut(&BenchRow),
) -> crate::Result<Vec<BenchRow>> {
    if opts.reps < 1 {
        return Err(crate::Error::parameter("reps", "at least 1 timed pass"));
    }
    if !(0.0..=600.0).contains(&opts.warmup_s) {
        return Err(crate::Error::parameter(
            "warmup-ms",
            format!("between 0 and 600000 ms, got {}", opts.warmup_s * 1e3),
        ));
    }
    crate::scene::limits::validate_dimensions(opts.width, opts.height, 1, 0)?;
    for m in &opts.modes {
        if known_mode(m).is_none() {
            return Err(crate::Error::parameter(
                "mode",
                format!(
                    "unknown mode '{m}', expected one of {}, {}, {}, {}, {} or a prefetch \
                     variant (<mode>+pf, <mode>+nopf)",
                    MODES.join(", "),
                    COMPRESSED_MODES.join(", "),
                    PACKET_TUNING_MODES.join(", "),
                    SORTED_MODES.join(", "),
                    SLAB_MODES.join(", ")
                ),
            ));
        }
    }
    let protocol = Protocol::new(
        &mesh.positions,
        mesh.triangles.clone(),
        opts.width,
        opts.height,
    );
    let mut rows = Vec::new();
    for &t in &opts.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .map_err(|e| crate::Error::parameter("threads", e.to_string()))?;
        let threads = pool.current_num_threads();
        for m in &opts.modes {
            // Build time: median of 5 builds after a warm-up, in this pool.
            let mut times = Vec::new();
            let mut mode = None;
            for _ in 0..6 {
                // The previous build is freed before the next starts, as Embree's harness
                // releases its scene before committing the next: its memory is there to
                // be reused rather than held while the next build faults in fresh pages.
                drop(mode.take());
                let start = Instant::now();
                let built = pool
                    .install(|| build_mode(m, &mesh.triangles))
                    .expect("mode names were checked");
                times.push(start.elapsed().as_secs_f64() * 1e3);
                mode = Some(built);
            }
            let mode = mode.expect("built at least once");
            let timing = Timing {
                reps: opts.reps,
                warmup_s: opts.warmup_s,
                retry_busy: opts.retry_busy,
            };
            for row in pool
                .install(|| run_mode_timed(&protocol, mode.as_ref(), threads, &timing, &times[1..]))
            {
                report(&row);
                rows.push(row);
            }
        }
    }
    Ok(rows)
}
