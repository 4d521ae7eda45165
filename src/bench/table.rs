//! The human-readable tables `bench` prints.

use super::timing::BenchRow;

/// A fixed-width table row for humans.
pub fn table_header() -> String {
    format!(
        "{:<12} {:<8} {:>7} {:>9} {:>9} {:>16} {:>9} {:>9} {:>9} {:>9} {:>5} {:>9}",
        "mode",
        "workload",
        "threads",
        "rays",
        "hits/occ",
        "sum_t",
        "Mrays/s",
        "min",
        "max",
        "build ms",
        "cpu",
        "bytes/tri"
    )
}

pub fn table_row(r: &BenchRow) -> String {
    format!(
        "{:<12} {:<8} {:>7} {:>9} {:>9} {:>16.6} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>5.2} {:>9.1}",
        r.mode,
        r.workload,
        r.threads,
        r.rays,
        r.hits_or_occluded,
        r.sum_t,
        r.mrays_median,
        r.mrays_min,
        r.mrays_max,
        r.build_ms,
        r.cpu_util,
        r.bytes_per_triangle
    )
}

/// The sweep's table (`bench --sweep`): per size and figure, Mrays/s (median, min,
/// max), the CPU share of the timed passes, build time (median, min, max) and bytes
/// per triangle.
pub fn sweep_table_header() -> String {
    format!(
        "{:>10} {:<12} {:<8} {:>7} {:>9} {:>9} {:>9} {:>5} {:>10} {:>10} {:>10} {:>9}",
        "triangles",
        "mode",
        "workload",
        "threads",
        "Mrays/s",
        "min",
        "max",
        "cpu",
        "build ms",
        "min",
        "max",
        "bytes/tri"
    )
}

pub fn sweep_table_row(r: &BenchRow) -> String {
    format!(
        "{:>10} {:<12} {:<8} {:>7} {:>9.2} {:>9.2} {:>9.2} {:>5.2} {:>10.2} {:>10.2} {:>10.2} {:>9.1}",
        r.triangles,
        r.mode,
        r.workload,
        r.threads,
        r.mrays_median,
        r.mrays_min,
        r.mrays_max,
        r.cpu_util,
        r.build_ms,
        r.build_ms_min,
        r.build_ms_max,
        r.bytes_per_triangle
    )
}
