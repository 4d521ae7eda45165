//! Unit tests of the N-wide BVH internals (stack need, parallel collapse, packet bounds).
use super::collapse::Collapse;
use super::node::{BvhNode, EMPTY_CHILD, NodeWidth, WideNode, Width};
use super::packet_bounds::PacketBounds;
use super::packet_setup::PacketSetup;
use super::qnode::QNode;
use super::stack::{PACKET_STACK, SINGLE_STACK};
use super::tree::{Bvh, Bvh4, Bvh8, wide_build_options};
use crate::accel::sah_build::build_tree;
use crate::accel::{Accel, Primitives, Triangles};
use crate::geometry::{ROBUST_FAR_SCALE, Ray, RayPacket};
use crate::simd::Packet;
use glam::Vec3;

fn soup() -> Triangles {
    let mut corners = Vec::new();
    let mut s = 7u32;
    let mut r = || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    };
    for _ in 0..3000 {
        let c = Vec3::new(r(), r(), r()) * 10.0;
        corners.push([
            c,
            c + Vec3::new(r(), r(), 0.1),
            c + Vec3::new(0.2, r(), r()),
        ]);
    }
    Triangles::from_corners(&corners)
}

/// A tree too deep for the packet stack traces its packets ray by ray, with the same
/// answers as the packet kernels.
#[test]
fn packets_of_a_tree_too_deep_for_the_packet_stack_go_ray_by_ray() {
    let mut bvh = Bvh8::build(soup());
    assert!(bvh.stack_need > 0 && bvh.stack_need < PACKET_STACK);
    let rays: Vec<Ray> = (0..512)
        .map(|i| {
            let a = i as f32 * 0.37;
            Ray::new(
                Vec3::new(5.0, 5.0, -20.0),
                Vec3::new(a.cos() * 0.2, a.sin() * 0.2, 1.0),
            )
        })
        .collect();
    let mut packet = vec![None; rays.len()];
    let mut packet_occ = vec![false; rays.len()];
    bvh.closest_hit_batch(&rays, &mut packet);
    bvh.any_hit_batch(&rays, &mut packet_occ);
    assert!(packet.iter().filter(|h| h.is_some()).count() > 50);
    bvh.stack_need = PACKET_STACK;
    let mut deep = vec![None; rays.len()];
    let mut deep_occ = vec![false; rays.len()];
    bvh.closest_hit_batch(&rays, &mut deep);
    bvh.any_hit_batch(&rays, &mut deep_occ);
    assert_eq!(packet, deep);
    assert_eq!(packet_occ, deep_occ);
}

/// Collapsing the top levels in parallel gives exactly the serial layout.
#[test]
fn parallel_collapse_lays_out_the_serial_tree() {
    fn layout<const N: usize, P: Primitives>(prims: &P, levels: usize) -> Vec<u32> {
        let (tree, ids) = build_tree(prims, wide_build_options(prims.as_triangles().is_some()));
        let mut c = Collapse::<N> {
            ids: &ids,
            triangles: prims.as_triangles(),
            nodes: crate::pages::LargeVec::new(),
            groups: crate::pages::LargeVec::new(),
        };
        let root = c.collapse(&tree.expect("non-empty"), levels);
        // every bit of the arrays, NaN corners of unused lanes included
        let mut bits = vec![root];
        for n in &c.nodes {
            bits.extend(n.planes.iter().flatten().map(|x| x.to_bits()));
            bits.extend(n.children);
        }
        for g in &c.groups {
            bits.extend(g.v.iter().flatten().flatten().map(|x| x.to_bits()));
            bits.extend(g.ids);
        }
        bits
    }
    let tris = soup();
    assert_eq!(layout::<8, _>(&tris, 0), layout::<8, _>(&tris, 3));
    assert_eq!(layout::<4, _>(&tris, 0), layout::<4, _>(&tris, 2));
    let centers: Vec<Vec3> = (0..500)
        .map(|i| Vec3::new(i as f32, (i * 7 % 13) as f32, 0.0))
        .collect();
    let spheres = crate::accel::Spheres {
        center: centers,
        radius: vec![0.4; 500],
    };
    assert_eq!(layout::<8, _>(&spheres, 0), layout::<8, _>(&spheres, 2));
}

/// The whole-packet node test never drops a child that some lane's own slab test
/// enters: every node of both widths against packets of many shapes (shared and
/// scattered origins, narrow and wide cones, nearly axis-parallel directions with
/// huge reciprocals, intervals starting late and ending early).
#[test]
fn packet_bounds_never_cull_a_child_a_lane_enters() {
    fn check<const N: usize>(bvh: &Bvh<Triangles, N>, rays: &[Ray]) -> (u64, u64)
    where
        Width<N>: NodeWidth,
    {
        let packet = RayPacket::from_rays(rays);
        let setup = PacketSetup::<Packet>::new(&packet);
        let (mut entered, mut kept) = (0, 0);
        for g in 0..setup.groups.min(3) {
            let p = setup.group(g);
            let mask = setup.group_mask[g];
            let shared = setup.shared_origin;
            let bounds =
                PacketBounds::<<Width<N> as NodeWidth>::L>::new(&p, mask, p.tmax(), shared, true);
            let tcull = p.tmax() * Packet::splat(ROBUST_FAR_SCALE);
            for node in &bvh.nodes {
                let cand = bounds.candidates(&node.planes, &node.children);
                for c in 0..N {
                    if node.children[c] == EMPTY_CHILD {
                        continue;
                    }
                    let bits = p.child_test(&node.planes, c, tcull).1;
                    if bits & mask != 0 {
                        entered += 1;
                        assert!(cand >> c & 1 == 1, "child {c} culled, lanes {bits:b}");
                    }
                    kept += u64::from(cand >> c & 1);
                }
            }
        }
        (entered, kept)
    }
    let tris = soup();
    let (b4, b8) = (Bvh4::build(tris.clone()), Bvh8::build(tris));
    let mut s = 99u32;
    let mut r = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    };
    let (mut entered, mut kept) = (0, 0);
    for trial in 0..120 {
        let spread = [0.0, 1e-3, 0.5, 4.0][trial % 4];
        let cone = [1e-3, 0.05, 0.4][trial % 3];
        // Origins before the soup, inside it (boxes behind some lanes, on every axis)
        // and past it, looking along +z and -z.
        let (z0, dz) = match trial % 6 {
            0 | 1 => (-10.0, 1.0),
            2 | 3 => (3.0, 1.0),
            4 => (3.0, -1.0),
            _ => (20.0, -1.0),
        };
        let base = Vec3::new(5.0, 5.0, z0) + Vec3::new(r(), r(), r()) * 4.0;
        let axis = if trial % 5 == 0 {
            Vec3::new(1e-7, 2e-7, dz) // reciprocals near 1e7
        } else {
            (Vec3::new(r(), r(), 8.0 * dz) - Vec3::splat(0.5)).normalize()
        };
        let rays: Vec<Ray> = (0..16)
            .map(|_| {
                let o = base + Vec3::new(r(), r(), r()) * spread;
                let d = (axis + Vec3::new(r() - 0.5, r() - 0.5, 0.0) * cone).normalize();
                let (tmin, tmax) = if trial % 7 == 0 {
                    (5.0, 14.0)
                } else {
                    (0.0, f32::INFINITY)
                };
                Ray::segment(o, d, tmin, tmax)
            })
            .collect();
        for (e, k) in [check(&b4, &rays), check(&b8, &rays)] {
            entered += e;
            kept += k;
        }
    }
    assert!(
        entered > 1000,
        "too few entered children to check: {entered}"
    );
    assert!(
        kept < 3 * entered,
        "the bounds cull little: {kept} kept, {entered} entered"
    );
}

/// The stack need is the largest sum of (children - 1) along a path, and within the
/// single-ray capacity.
#[test]
fn stack_need_bounds_the_pending_entries() {
    let b4 = Bvh4::build(soup());
    let b8 = Bvh8::build(soup());
    assert!(b4.stack_need <= 3 * b4.info.max_depth);
    assert!(b8.stack_need <= 7 * b8.info.max_depth);
    assert!(b8.info.max_depth < b4.info.max_depth);
    assert!(b8.stack_need < SINGLE_STACK);
}

/// A compressed tree is the exact tree with its boxes rounded outward: the same child
/// references node for node, every quantised child box containing the exact one, half
/// (BVH8) or a quarter (BVH4) of the node bytes; both validate.
#[test]
fn compressed_nodes_contain_the_exact_boxes_of_the_same_tree() {
    fn check<const N: usize>(tris: &Triangles)
    where
        Width<N>: NodeWidth,
    {
        let exact = Bvh::<Triangles, N>::build(tris.clone());
        let comp = Bvh::<Triangles, N, QNode<N>>::build(tris.clone());
        exact.validate().expect("the exact tree validates");
        comp.validate().expect("the compressed tree validates");
        assert_eq!(exact.nodes.len(), comp.nodes.len());
        let mut looser = 0;
        for (e, c) in exact.nodes.iter().zip(&comp.nodes) {
            assert_eq!(e.children, c.children);
            for slot in (0..N).filter(|&s| e.children[s] != EMPTY_CHILD) {
                let (eb, cb) = (e.child_bounds(slot), c.child_bounds(slot));
                assert!(
                    cb.min.cmple(eb.min).all() && cb.max.cmpge(eb.max).all(),
                    "{cb:?} does not contain {eb:?}"
                );
                looser += usize::from(cb != eb);
            }
        }
        assert!(looser > 0, "quantisation never rounded: suspicious");
        let node_bytes = |b: usize| b * exact.nodes.len();
        assert_eq!(
            exact.info.memory_bytes - comp.info.memory_bytes,
            node_bytes(size_of::<BvhNode<N>>() - size_of::<QNode<N>>())
        );
    }
    let tris = soup();
    check::<4>(&tris);
    check::<8>(&tris);
}

/// `validate()` catches a quantised box that no longer contains its subtree: one
/// maximum offset lowered by one step.
#[test]
fn validate_rejects_a_box_rounded_the_wrong_way() {
    let mut comp = Bvh::<Triangles, 8, QNode<8>>::build(soup());
    comp.validate().expect("as built");
    let root = comp.root as usize;
    let slot = (0..8)
        .find(|&s| comp.nodes[root].children[s] != EMPTY_CHILD && comp.nodes[root].q[3][s] > 0)
        .expect("a child with a positive max-x offset");
    comp.nodes[root].q[3][slot] -= 1;
    let e = comp
        .validate()
        .expect_err("a shrunken box must be reported");
    assert!(e.contains("does not contain"), "{e}");
}

/// A mesh large enough for the builder's huge-page arrays (>= 4 MiB of references) and
/// its parallel binning and partition builds trees that validate, with 1 and 2
/// threads, and both trees are the same (the parallel paths write what the serial ones
/// do).
#[test]
fn large_builds_validate_at_one_and_two_threads() {
    let tris = crate::bench::BenchMesh::procedural(150_000).triangles;
    assert!(tris.count() * 32 >= 4 << 20, "{} triangles", tris.count());
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| Bvh8::build(tris.clone()))
    };
    let (one, two) = (build(1), build(2));
    for bvh in [&one, &two] {
        bvh.validate().expect("the tree validates");
    }
    let (a, b) = (one.info(), two.info());
    assert_eq!((a.nodes, a.leaves), (b.nodes, b.leaves));
    assert_eq!(a.sah_cost.to_bits(), b.sah_cost.to_bits());
    #[cfg(target_os = "linux")]
    for (threads, bvh) in [(1, &one), (2, &two)] {
        let super::tree::Leaves::Triangles(groups) = &bvh.leaves else {
            panic!("triangle leaves")
        };
        tree_arrays_are_advised(threads, &bvh.nodes, groups);
    }
}

/// The triangle groups of a tree whose groups reach
/// [`MAPPED_MIN_BYTES`](crate::pages::MAPPED_MIN_BYTES) lie in a mapping of their own,
/// 2 MiB-aligned and advised for huge pages (`hg` in `/proc/self/smaps`) before the
/// build wrote them (`pages::LargeVec`); so do the nodes where their array is that
/// large: at 1 thread always (its room, a node per two triangles, is reserved before
/// the collapse counts them), at 2 threads where the nodes themselves reach it.
#[cfg(target_os = "linux")]
fn tree_arrays_are_advised<T: Copy, G: Copy>(
    threads: usize,
    nodes: &crate::pages::LargeVec<T>,
    groups: &crate::pages::LargeVec<G>,
) {
    use crate::pages::MAPPED_MIN_BYTES;
    let node_bytes = size_of_val(&nodes[..]);
    let group_bytes = size_of_val(&groups[..]);
    assert!(
        group_bytes >= MAPPED_MIN_BYTES,
        "{group_bytes} bytes of groups"
    );
    assert_eq!(
        nodes.is_mapped(),
        threads == 1 || node_bytes >= MAPPED_MIN_BYTES,
        "{threads} threads, {node_bytes} bytes of nodes"
    );
    assert!(groups.is_mapped(), "{threads} threads: groups on the heap");
    for (what, mapped, ptr) in [
        ("nodes", nodes.is_mapped(), nodes.as_ptr() as usize),
        ("groups", true, groups.as_ptr() as usize),
    ] {
        if !mapped {
            continue;
        }
        assert_eq!(ptr % (2 << 20), 0, "{what} not 2 MiB-aligned");
        let flags = crate::pages::vm_flags_at(ptr).expect("the mapping in smaps");
        assert!(
            flags.iter().any(|f| f == "hg"),
            "{what} not advised: {flags:?}"
        );
    }
}

/// A small tree's arrays (under `MAPPED_MIN_BYTES`) stay ordinary heap buffers, at 1
/// and 2 threads.
#[test]
fn small_trees_keep_heap_arrays() {
    let tris = soup();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let bvh = pool.install(|| Bvh8::build(tris.clone()));
        let super::tree::Leaves::Triangles(groups) = &bvh.leaves else {
            panic!("triangle leaves")
        };
        assert!(
            !groups.is_mapped() && !bvh.nodes.is_mapped(),
            "{threads} threads"
        );
    }
}
