//! `bench --triangles N` and `bench --sweep`: the protocol over the procedural mesh (a
//! bumpy sphere, `scene::procedural::tessellated_mesh`) at a chosen size, or at every
//! power of ten from 10^3 triangles up to a limit, so that what size costs (build time,
//! bytes per triangle, Mrays/s) shows in one table.

use super::{BenchMesh, BenchOptions, BenchRow, run};
use crate::error::{Error, Result};

/// The smallest size of a sweep.
pub const SWEEP_MIN_TRIANGLES: usize = 1_000;
/// The default largest size of a sweep.
pub const SWEEP_MAX_TRIANGLES: usize = 10_000_000;
/// The largest procedural mesh `bench` accepts (the scene files' limit for the same
/// generator).
pub const MAX_BENCH_TRIANGLES: usize = 50_000_000;

/// Checks a requested procedural mesh size.
pub fn check_triangles(what: &str, n: usize) -> Result<()> {
    if (1..=MAX_BENCH_TRIANGLES).contains(&n) {
        Ok(())
    } else {
        Err(Error::parameter(
            what,
            format!("must be between 1 and {MAX_BENCH_TRIANGLES} triangles, got {n}"),
        ))
    }
}

/// The sizes of a sweep up to `max`: 10^3, 10^4, ... while at most `max`.
pub fn sweep_sizes(max: usize) -> Result<Vec<usize>> {
    check_triangles("sweep-max", max)?;
    if max < SWEEP_MIN_TRIANGLES {
        return Err(Error::parameter(
            "sweep-max",
            format!("a sweep starts at {SWEEP_MIN_TRIANGLES} triangles, got a limit of {max}"),
        ));
    }
    let mut sizes = Vec::new();
    let mut n = SWEEP_MIN_TRIANGLES;
    while n <= max {
        sizes.push(n);
        n *= 10;
    }
    Ok(sizes)
}

/// Runs the protocol at every size of the sweep up to `max` (one procedural mesh at a
/// time, dropped before the next is made). `size` is told each mesh before its rows;
/// `report` receives each row as it is measured.
pub fn run_sweep(
    max: usize,
    opts: &BenchOptions,
    mut size: impl FnMut(&BenchMesh),
    mut report: impl FnMut(&BenchRow),
) -> Result<Vec<BenchRow>> {
    let sizes = sweep_sizes(max)?;
    let mut rows = Vec::new();
    for n in sizes {
        let mesh = BenchMesh::procedural(n);
        size(&mesh);
        rows.extend(run(&mesh, opts, &mut report)?);
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_sizes_are_the_powers_of_ten_up_to_the_limit() {
        assert_eq!(sweep_sizes(1_000).unwrap(), vec![1_000]);
        assert_eq!(sweep_sizes(99_999).unwrap(), vec![1_000, 10_000]);
        assert_eq!(
            sweep_sizes(SWEEP_MAX_TRIANGLES).unwrap(),
            vec![1_000, 10_000, 100_000, 1_000_000, 10_000_000]
        );
        for bad in [0, 999, MAX_BENCH_TRIANGLES + 1] {
            let e = sweep_sizes(bad).unwrap_err().to_string();
            assert!(e.contains("sweep-max"), "{e}");
        }
    }
}
