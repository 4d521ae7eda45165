//! Shared by the integration tests: deterministic generators (random numbers, rays and
//! primitive sets that need no files), scratch directories (`temp::temp_dir`,
//! `temp::write`) and the binary under test (`bin::bin`, `bin::run`).
#![allow(dead_code)]

pub mod bin;
pub mod temp;

use glam::Vec3;
use packet_render::accel::Triangles;
use packet_render::geometry::{Aabb, Ray};

/// splitmix64: small, fast, and good enough for test inputs.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    pub fn unit_vector(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    pub fn point_in(&mut self, b: &Aabb) -> Vec3 {
        Vec3::new(
            self.range(b.min.x, b.max.x),
            self.range(b.min.y, b.max.y),
            self.range(b.min.z, b.max.z),
        )
    }
}

/// A closed, bumpy UV sphere: indexed positions and triangles.
pub fn bumpy_sphere(rings: usize, segments: usize, radius: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut pos = vec![Vec3::new(0.0, radius, 0.0)];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let bump = 1.0 + 0.15 * (5.0 * theta).sin() * (3.0 * phi).cos();
            pos.push(
                radius
                    * bump
                    * Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    ),
            );
        }
    }
    pos.push(Vec3::new(0.0, -radius, 0.0));
    let tris = uv_sphere_triangles(rings, segments);
    (pos, tris)
}

/// Triangles of a UV sphere whose vertices are the north pole, `rings - 1` rings of
/// `segments` vertices from north to south, then the south pole; the seam is shared.
pub fn uv_sphere_triangles(rings: usize, segments: usize) -> Vec<[u32; 3]> {
    let south = (1 + (rings - 1) * segments) as u32;
    let ring = |r: usize, s: usize| (1 + (r - 1) * segments + s % segments) as u32;
    let mut tris = Vec::new();
    for s in 0..segments {
        tris.push([0, ring(1, s + 1), ring(1, s)]);
        tris.push([south, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s),
                ring(r + 1, s + 1),
            );
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    tris
}

pub fn triangles_of(pos: &[Vec3], tris: &[[u32; 3]]) -> Triangles {
    let corners: Vec<[Vec3; 3]> = tris
        .iter()
        .map(|t| [pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]])
        .collect();
    Triangles::from_corners(&corners)
}

/// Random triangles of mixed sizes in a box (overlapping, intersecting, some slivers).
pub fn triangle_soup(n: usize, seed: u64) -> Triangles {
    let mut rng = Rng(seed);
    let b = Aabb::new(Vec3::splat(-5.0), Vec3::splat(5.0));
    let corners: Vec<[Vec3; 3]> = (0..n)
        .map(|i| {
            let c = rng.point_in(&b);
            let size = if i % 10 == 0 { 3.0 } else { 0.4 };
            let sliver = if i % 17 == 0 { 1e-4 } else { 1.0 };
            let e1 = size * rng.unit_vector();
            let e2 = sliver * size * rng.unit_vector();
            [c, c + e1, c + e2]
        })
        .collect();
    Triangles::from_corners(&corners)
}

/// The tessellated mesh of `scene::procedural` with about `n` triangles.
pub fn procedural_mesh(n: usize) -> Triangles {
    let mut b = packet_render::scene::SceneBuilder::new();
    let m = b.add_material(packet_render::scene::Material::default());
    packet_render::scene::procedural::tessellated_mesh(&mut b, n, Vec3::ZERO, 1.0, m);
    Triangles::from_mesh(&b.mesh)
}

/// `n` rays: a third from outside the bounds toward random interior points, a third
/// from random interior points in random directions, a third axis-parallel (with both
/// signed zeros in the other components).
pub fn random_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng(seed);
    let c = bounds.center();
    let grown = Aabb::new(c + 1.5 * (bounds.min - c), c + 1.5 * (bounds.max - c));
    (0..n)
        .map(|i| match i % 3 {
            0 => {
                let o = c + grown.diagonal() * rng.unit_vector();
                let target = rng.point_in(bounds);
                Ray::new(o, (target - o).normalize())
            }
            1 => Ray::new(rng.point_in(&grown), rng.unit_vector()),
            _ => {
                let axis = (rng.next_u64() % 3) as usize;
                let mut d = Vec3::ZERO;
                d[axis] = if rng.next_u64().is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                };
                for k in 0..3 {
                    if k != axis && rng.next_u64().is_multiple_of(2) {
                        d[k] = -0.0;
                    }
                }
                Ray::new(rng.point_in(&grown), d)
            }
        })
        .collect()
}
