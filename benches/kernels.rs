//! Criterion benches for the kernels behind `packet-render bench`: BVH builds
//! (Mtriangles/s) and the three tracing modes on the protocol's workloads, on the
//! procedural Bunny-scale mesh (no model files needed).
//!
//! `cargo bench --bench kernels` (add `-- build` or `-- trace` to pick a group).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use packet_render::accel::{Bvh2, Bvh4, Bvh8, Primitives};
use packet_render::bench::{BenchMesh, MODES, Protocol, Workload, build_mode};
use std::hint::black_box;

fn mesh() -> BenchMesh {
    BenchMesh::procedural(packet_render::bench::DEFAULT_MESH_TRIANGLES)
}

fn builds(c: &mut Criterion) {
    let mesh = mesh();
    let tris = &mesh.triangles;
    let mut g = c.benchmark_group("build");
    g.sample_size(20);
    g.throughput(Throughput::Elements(tris.count() as u64));
    g.bench_function("bvh2", |b| b.iter(|| black_box(Bvh2::build(tris.clone()))));
    g.bench_function("bvh4", |b| b.iter(|| black_box(Bvh4::build(tris.clone()))));
    g.bench_function("bvh8", |b| b.iter(|| black_box(Bvh8::build(tris.clone()))));
    g.finish();
}

fn traversal(c: &mut Criterion) {
    let mesh = mesh();
    // 256x256 keeps one iteration short; the rays are the protocol's.
    let protocol = Protocol::new(&mesh.positions, mesh.triangles.clone(), 256, 256);
    let mut g = c.benchmark_group("trace");
    g.sample_size(10);
    for name in MODES {
        let mode = build_mode(name, &mesh.triangles).expect("known mode");
        let primary = protocol.primary_hits(mode.as_ref());
        let mut t = vec![0.0; 256 * 256];
        let mut prim = vec![0; 256 * 256];
        let mut occ = vec![0; 256 * 256];
        for workload in Workload::ALL {
            let p = (workload != Workload::Primary).then_some(&primary);
            let rays = protocol.pass(mode.as_ref(), workload, p, &mut t, &mut prim, &mut occ);
            g.throughput(Throughput::Elements(rays));
            g.bench_with_input(
                BenchmarkId::new(*name, workload.name()),
                &workload,
                |b, &w| b.iter(|| protocol.pass(mode.as_ref(), w, p, &mut t, &mut prim, &mut occ)),
            );
        }
    }
    g.finish();
}

criterion_group!(benches, builds, traversal);
criterion_main!(benches);
