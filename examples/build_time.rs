//! Times the BVH8 build alone: `cargo run --release --example build_time -- MESH.obj|N
//! [reps] [threads] [--obj OUT.obj]`. Prints build ms (min/median/max over `reps`
//! builds after one warm-up), Mtriangles/s at the median, the process CPU time per
//! build (min/median/max: on a loaded machine wall time counts the other processes'
//! turns too; CPU time over wall time is the share the build got, `cpu` as Embree's
//! harness prints it), the SAH cost, the node and leaf counts and bytes of nodes and
//! leaves per triangle, and the process's peak resident memory per triangle (Linux
//! `VmHWM`: the mesh and its copy for the build included; the build's own arrays are
//! 2 x 32 bytes of references and 4 bytes of ids per triangle on top of the tree).
//! It also prints the median count of minor page faults per build (fresh pages the
//! kernel zeroes on first touch: the arrays of a build not recycled by the allocator
//! from the previous one). `--obj OUT.obj` also writes
//! the mesh as an OBJ (three vertices per triangle) for Embree's harness, which reads
//! only files.

use packet_render::accel::AccelKind;
use packet_render::bench::BenchMesh;
use packet_render::bench::cpu_time::process_cpu_seconds;
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

/// The process's minor page faults so far (`getrusage`), where the system reports them:
/// each is a page the kernel hands over, zeroed, on first touch.
fn minor_faults() -> Option<i64> {
    #[cfg(unix)]
    {
        // SAFETY: `getrusage` fills the struct it is given; all-zero is a valid value.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: a valid pointer to a live `rusage`.
        (unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } == 0).then_some(u.ru_minflt)
    }
    #[cfg(not(unix))]
    None
}

/// The process's peak resident set in bytes (`VmHWM` in `/proc/self/status`), where
/// the kernel reports it.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
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
    if let Some(path) = obj
        && let Err(e) = write_obj(&mesh, &path)
    {
        eprintln!("cannot write {path}: {e}");
        std::process::exit(1);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let (mut ms, mut cpu_ms, mut faults) = (Vec::new(), Vec::new(), Vec::new());
    let mut info = None;
    for i in 0..=reps {
        let tris = mesh.triangles.clone();
        let (c0, f0) = (process_cpu_seconds(), minor_faults());
        let accel = pool.install(|| AccelKind::Bvh8.build(tris));
        let (c1, f1) = (process_cpu_seconds(), minor_faults());
        let inf = accel.info();
        if i > 0 {
            ms.push(inf.build_ms);
            if let (Some(a), Some(b)) = (c0, c1) {
                cpu_ms.push((b - a) * 1e3);
            }
            if let (Some(a), Some(b)) = (f0, f1) {
                faults.push(b - a);
            }
        }
        drop(accel);
        info = Some(inf);
    }
    ms.sort_by(f64::total_cmp);
    cpu_ms.sort_by(f64::total_cmp);
    let cpu = if cpu_ms.is_empty() {
        "cpu ms unavailable".to_string()
    } else {
        format!(
            "cpu ms min {:.2} median {:.2} max {:.2} (Mtri/s per thread at the median {:.2})",
            cpu_ms[0],
            cpu_ms[cpu_ms.len() / 2],
            cpu_ms[cpu_ms.len() - 1],
            info.as_ref().map_or(0, |i| i.primitives) as f64 / cpu_ms[cpu_ms.len() / 2] / 1e3,
        )
    };
    faults.sort_unstable();
    let faults = match faults.get(faults.len() / 2) {
        Some(f) => format!("  page faults per build (median) {f}"),
        None => String::new(),
    };
    let info = info.expect("at least one build");
    let peak = match peak_rss_bytes() {
        Some(b) => format!(
            "peak RSS {:.1} MB ({:.0} bytes/tri)",
            b as f64 / 1e6,
            b as f64 / info.primitives.max(1) as f64
        ),
        None => "peak RSS unavailable".to_string(),
    };
    println!(
        "{} tris={} threads={threads} build ms min {:.2} median {:.2} max {:.2} Mtri/s {:.2}  {cpu}  sah {:.4} nodes {} leaves {} bytes/tri {:.1}  {peak}{faults}",
        mesh.name,
        info.primitives,
        ms[0],
        ms[ms.len() / 2],
        ms[ms.len() - 1],
        info.primitives as f64 / ms[ms.len() / 2] / 1e3,
        info.sah_cost,
        info.nodes,
        info.leaves,
        info.memory_bytes as f64 / info.primitives.max(1) as f64,
    );
    Ok(())
}
