//! Times one workload of one bench mode, 1 thread, with no other mode's work around it
//! (for `perf record`): `cargo run --release --example stream_profile -- MESH.obj|N MODE
//! WORKLOAD [reps]`. Prints Mrays/s min/median/max and the checksums.

use packet_render::bench::{BenchMesh, Protocol, Timing, Workload, build_mode, median};

fn main() -> packet_render::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("69451", String::as_str);
    let mode = args.get(2).map_or("bvh8-stream", String::as_str);
    let workload = match args.get(3).map_or("diffuse", String::as_str) {
        "primary" => Workload::Primary,
        "shadow" => Workload::Shadow,
        _ => Workload::Diffuse,
    };
    let reps: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(7);
    let mesh = match what.parse::<usize>() {
        Ok(n) => BenchMesh::procedural(n),
        Err(_) => BenchMesh::from_obj(std::path::Path::new(what))?,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let protocol = Protocol::new(&mesh.positions, mesh.triangles.clone(), 1024, 1024);
        let Some(m) = build_mode(mode, &protocol.tris) else {
            eprintln!("unknown mode {mode}");
            return;
        };
        let primary = protocol.primary_hits(m.as_ref());
        let p = (workload != Workload::Primary).then_some(&primary);
        let r = protocol.measure(m.as_ref(), workload, p, &Timing::passes(reps));
        let min = r.rates.iter().copied().fold(f64::INFINITY, f64::min);
        let max = r.rates.iter().copied().fold(0.0, f64::max);
        println!(
            "{mode} {} min {min:.2} median {:.2} max {max:.2} cpu {:.2} hits {} sum_t {:.6}",
            workload.name(),
            median(&r.rates),
            r.cpu_util,
            r.checksums.hits_or_occluded,
            r.checksums.sum_t
        );
    });
    Ok(())
}
