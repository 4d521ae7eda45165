//! Times the BVH8 build alone: `cargo run --release --example build_time -- MESH.obj|N
//! [reps] [threads]`. Prints build ms (min/median/max over `reps` builds after one
//! warm-up), the SAH cost and the node count.

use packet_render::accel::AccelKind;
use packet_render::bench::BenchMesh;

fn main() -> packet_render::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("69451", String::as_str);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(7);
    let threads: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let mesh = match what.parse::<usize>() {
        Ok(n) => BenchMesh::procedural(n),
        Err(_) => BenchMesh::from_obj(std::path::Path::new(what))?,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let mut ms = Vec::new();
    let mut info = None;
    for i in 0..=reps {
        let accel = pool.install(|| AccelKind::Bvh8.build(mesh.triangles.clone()));
        let inf = accel.info();
        if i > 0 {
            ms.push(inf.build_ms);
        }
        info = Some(inf);
    }
    ms.sort_by(f64::total_cmp);
    let info = info.expect("at least one build");
    println!(
        "{} tris={} threads={threads} build ms min {:.2} median {:.2} max {:.2}  sah {:.4} nodes {} leaves {} Mtri/s {:.2}",
        mesh.name,
        info.primitives,
        ms[0],
        ms[ms.len() / 2],
        ms[ms.len() - 1],
        info.sah_cost,
        info.nodes,
        info.leaves,
        info.primitives as f64 / ms[ms.len() / 2] / 1e3,
    );
    Ok(())
}
