//! Times the BVH8 build alone: `cargo run --release --example build_time -- MESH.obj|N
//! [reps] [threads] [--obj OUT.obj]`. Prints build ms (min/median/max over `reps`
//! builds after one warm-up), Mtriangles/s at the median, the SAH cost, the node and
//! leaf counts and bytes of nodes and leaves per triangle. `--obj OUT.obj` also writes
//! the mesh as an OBJ (three vertices per triangle) for Embree's harness, which reads
//! only files.

use packet_render::accel::AccelKind;
use packet_render::bench::BenchMesh;
use std::io::Write;

fn write_obj(mesh: &BenchMesh, path: &str) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    let t = &mesh.triangles;
    for i in 0..t.v0.len() {
        for p in [t.v0[i], t.v1[i], t.v2[i]] {
            writeln!(f, "v {} {} {}", p.x, p.y, p.z)?;
        }
    }
    for i in 0..t.v0.len() {
        let k = 3 * i + 1;
        writeln!(f, "f {} {} {}", k, k + 1, k + 2)?;
    }
    f.flush()
}

fn main() -> packet_render::Result<()> {
    let mut args: Vec<String> = std::env::args().collect();
    let obj = match args.iter().position(|a| a == "--obj") {
        Some(i) if i + 1 < args.len() => {
            let p = args.remove(i + 1);
            args.remove(i);
            Some(p)
        }
        Some(_) => {
            eprintln!("--obj needs a file name");
            std::process::exit(2);
        }
        None => None,
    };
    let what = args.get(1).map_or("69451", String::as_str);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(7).max(1);
    let threads: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let mesh = match what.parse::<usize>() {
        Ok(n) => BenchMesh::procedural(n),
        Err(_) => BenchMesh::from_obj(std::path::Path::new(what))?,
    };
    if let Some(path) = obj {
        if let Err(e) = write_obj(&mesh, &path) {
            eprintln!("cannot write {path}: {e}");
            std::process::exit(1);
        }
    }
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
        "{} tris={} threads={threads} build ms min {:.2} median {:.2} max {:.2}  sah {:.4} nodes {} leaves {} Mtri/s {:.2} bytes/tri {:.1}",
        mesh.name,
        info.primitives,
        ms[0],
        ms[ms.len() / 2],
        ms[ms.len() - 1],
        info.sah_cost,
        info.nodes,
        info.leaves,
        info.primitives as f64 / ms[ms.len() / 2] / 1e3,
        info.memory_bytes as f64 / info.primitives.max(1) as f64,
    );
    Ok(())
}
