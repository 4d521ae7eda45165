//! Shared by the `robustness_*` suites: closed test meshes with shared vertices, and
//! "every path" tracing: each structure of `AccelKind::ALL` through its single-ray entry
//! point (scalar for brute force and BVH2, the SIMD kernel for BVH4) and through its
//! packet entry point with rays grouped 16 at a time.
#![allow(dead_code)]

use glam::Vec3;
use packet_render::accel::{Accel, AccelKind, Primitives, Triangles};
use packet_render::geometry::{Hit, Ray};

/// Rays per packet, as the renderer groups them.
pub const PACKET: usize = 16;

/// An indexed closed mesh: shared vertices, so shared edges are bit-identical.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub pos: Vec<Vec3>,
    pub tris: Vec<[u32; 3]>,
    /// Points strictly inside the mesh (for rays that must never escape).
    pub inside: Vec<Vec3>,
    /// Every face lies on the boundary of the convex hull.
    pub convex: bool,
}

impl Mesh {
    pub fn triangles(&self) -> Triangles {
        let c: Vec<[Vec3; 3]> = self
            .tris
            .iter()
            .map(|t| t.map(|i| self.pos[i as usize]))
            .collect();
        Triangles::from_corners(&c)
    }

    /// `p * s + offset` for every vertex and interior point.
    pub fn transformed(&self, s: f32, offset: Vec3) -> Mesh {
        Mesh {
            name: format!("{} x{s:e} +{offset:?}", self.name),
            pos: self.pos.iter().map(|p| *p * s + offset).collect(),
            inside: self.inside.iter().map(|p| *p * s + offset).collect(),
            ..self.clone()
        }
    }

    pub fn edges(&self) -> Vec<(Vec3, Vec3)> {
        let mut e: Vec<(u32, u32)> = self
            .tris
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        e.sort_unstable();
        e.dedup();
        e.iter()
            .map(|&(a, b)| (self.pos[a as usize], self.pos[b as usize]))
            .collect()
    }
}

pub fn cube() -> Mesh {
    let pos: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    // Two triangles per face, outward winding.
    let quads = [
        [0, 2, 3, 1], // z = -1
        [4, 5, 7, 6], // z = +1
        [0, 1, 5, 4], // y = -1
        [2, 6, 7, 3], // y = +1
        [0, 4, 6, 2], // x = -1
        [1, 3, 7, 5], // x = +1
    ];
    let tris = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh {
        name: "cube".into(),
        pos,
        tris,
        inside: vec![
            Vec3::ZERO,
            Vec3::new(0.3, -0.6, 0.1),
            Vec3::new(-0.9, 0.9, -0.9),
        ],
        convex: true,
    }
}

pub fn octahedron() -> Mesh {
    let pos = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let mut tris = Vec::new();
    for (x, y, z) in [
        (0u32, 2u32, 4u32),
        (2, 1, 4),
        (1, 3, 4),
        (3, 0, 4),
        (2, 0, 5),
        (1, 2, 5),
        (3, 1, 5),
        (0, 3, 5),
    ] {
        tris.push([x, y, z]);
    }
    Mesh {
        name: "octahedron".into(),
        pos,
        tris,
        inside: vec![
            Vec3::ZERO,
            Vec3::new(0.2, 0.1, -0.3),
            Vec3::new(-0.05, -0.4, 0.01),
        ],
        convex: true,
    }
}

/// A UV sphere whose vertices are jittered radially (so no two faces are coplanar by
/// construction), with the seam column and the poles shared.
pub fn jittered_sphere(rings: usize, segments: usize, jitter: f32, seed: u64) -> Mesh {
    let mut rng = crate::common::Rng(seed);
    let mut pos = vec![Vec3::Y];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let k = 1.0 + jitter * rng.range(-1.0, 1.0);
            pos.push(
                k * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ),
            );
        }
    }
    pos.push(-Vec3::Y);
    let tris = crate::common::uv_sphere_triangles(rings, segments);
    Mesh {
        name: format!("jittered sphere {rings}x{segments}"),
        pos,
        tris,
        // The radius never drops below 1 - jitter, and a UV sphere's faces stay close
        // to it: points well inside the inscribed ball.
        inside: vec![
            Vec3::ZERO,
            Vec3::new(0.2, -0.1, 0.15),
            Vec3::new(-0.3, 0.25, 0.0),
        ],
        convex: jitter == 0.0,
    }
}

/// A 64-sided pyramid: the apex is shared by 64 side triangles and the base centre by
/// 64 coplanar base triangles (a fan).
pub fn fan_cone(n: u32) -> Mesh {
    let mut pos = vec![Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO];
    for i in 0..n {
        let phi = std::f32::consts::TAU * i as f32 / n as f32;
        pos.push(Vec3::new(phi.cos(), phi.sin(), 0.0));
    }
    let ring = |i: u32| 2 + i % n;
    let mut tris = Vec::new();
    for i in 0..n {
        tris.push([0, ring(i), ring(i + 1)]);
        tris.push([1, ring(i + 1), ring(i)]);
    }
    Mesh {
        name: format!("{n}-fan cone"),
        pos,
        tris,
        inside: vec![
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(0.1, -0.2, 0.2),
            Vec3::new(0.0, 0.0, 0.01),
        ],
        convex: true,
    }
}

pub fn all_meshes() -> Vec<Mesh> {
    vec![
        cube(),
        octahedron(),
        jittered_sphere(16, 32, 0.05, 3),
        fan_cone(64),
    ]
}

/// Every structure in `AccelKind::ALL`, built over `prims`.
pub fn build_all<P: Primitives + Clone + 'static>(prims: &P) -> Vec<(AccelKind, Box<dyn Accel>)> {
    AccelKind::ALL
        .iter()
        .map(|&k| (k, k.build(prims.clone())))
        .collect()
}

/// Closest hits along every path: `"{kind}/single"` and `"{kind}/packet"`.
pub fn closest_all(
    accels: &[(AccelKind, Box<dyn Accel>)],
    rays: &[Ray],
) -> Vec<(String, Vec<Option<Hit>>)> {
    let mut out = Vec::new();
    for (k, a) in accels {
        out.push((
            format!("{k}/single"),
            rays.iter().map(|r| a.closest_hit(r)).collect(),
        ));
        let mut batch = vec![None; rays.len()];
        for (r, o) in rays.chunks(PACKET).zip(batch.chunks_mut(PACKET)) {
            a.closest_hit_batch(r, o);
        }
        out.push((format!("{k}/packet"), batch));
    }
    out
}

/// Occlusion along every path.
pub fn any_all(accels: &[(AccelKind, Box<dyn Accel>)], rays: &[Ray]) -> Vec<(String, Vec<bool>)> {
    let mut out = Vec::new();
    for (k, a) in accels {
        out.push((
            format!("{k}/single"),
            rays.iter().map(|r| a.any_hit(r)).collect(),
        ));
        let mut batch = vec![false; rays.len()];
        for (r, o) in rays.chunks(PACKET).zip(batch.chunks_mut(PACKET)) {
            a.any_hit_batch(r, o);
        }
        out.push((format!("{k}/packet"), batch));
    }
    out
}

/// Orders rays so that each packet of 16 shares a direction octant and dominant axis
/// where possible (what a camera packet looks like to the traversal).
pub fn coherent_order(rays: &mut [Ray]) {
    rays.sort_by_key(|r| {
        let d = r.dir;
        let octant = (d.x.is_sign_negative() as u32)
            | (d.y.is_sign_negative() as u32) << 1
            | (d.z.is_sign_negative() as u32) << 2;
        let a = d.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        (octant, axis)
    });
}

/// Geometric unit normal of triangle `i`, as `TriangleMesh::geometric_normal` computes it.
pub fn normal(t: &Triangles, i: usize) -> Vec3 {
    (t.v1[i] - t.v0[i])
        .cross(t.v2[i] - t.v0[i])
        .normalize_or_zero()
}

/// The hit point rebuilt from barycentrics and its error bound, as
/// `SurfaceInteraction::new` does.
pub fn hit_point(t: &Triangles, h: &Hit) -> (Vec3, Vec3) {
    let i = h.prim as usize;
    packet_render::geometry::triangle_point([t.v0[i], t.v1[i], t.v2[i]], h.u, h.v)
}

/// A secondary-ray origin exactly as the integrator computes it: the hit point offset
/// by its error bound to the side of `n_leaving`.
pub fn offset_origin(t: &Triangles, h: &Hit, n_leaving: Vec3) -> Vec3 {
    let (p, err) = hit_point(t, h);
    packet_render::geometry::offset_ray_origin(p, err, n_leaving, n_leaving)
}

/// Whether the hit point lies farther than `k` offset distances from every *sharp* edge
/// of its triangle: an edge whose neighbouring face turns by more than 90° (normals with
/// a negative dot product: a cone's rim). Moving a point inwards along its face normal
/// moves it towards such a neighbour's plane, so within a few offsets of that edge the
/// origin can land outside the thin wedge; f32 cannot place a point inside a wedge
/// thinner than a few ulps. At other edges the inward move only goes deeper. The offset
/// distance is what `offset_ray_origin` moves the point by (`|n|·p_error`, plus the
/// one-ulp rounding away per coordinate).
pub fn clear_of_sharp_edges(m: &Mesh, t: &Triangles, h: &Hit, k: f64) -> bool {
    let i = h.prim as usize;
    let (p, err) = hit_point(t, h);
    let n = normal(t, i);
    let off = n.abs().dot(err) as f64 + 2.0 * (p.abs().max_element() * f32::EPSILON) as f64;
    let c = [t.v0[i], t.v1[i], t.v2[i]].map(|v| v.as_dvec3());
    let b = [1.0 - h.u as f64 - h.v as f64, h.u as f64, h.v as f64];
    let twice_area = (c[1] - c[0]).cross(c[2] - c[0]).length();
    let tri = m.tris[i];
    (0..3).all(|j| {
        let (e0, e1) = (tri[(j + 1) % 3], tri[(j + 2) % 3]);
        let sharp = m.tris.iter().enumerate().any(|(o, ot)| {
            o != i && ot.contains(&e0) && ot.contains(&e1) && normal(t, o).dot(n) < 0.0
        });
        let edge = (c[(j + 2) % 3] - c[(j + 1) % 3]).length();
        !sharp || b[j] * twice_area / edge > k * off
    })
}
