//! Procedural scene generators: Haines' sphereflake, a tessellated "Bunny-scale"
//! stand-in mesh of any size, and Whitted's 1980 room.

use super::{Camera, Checker, Light, Material, SceneBuilder};
use glam::Vec3;
use std::f32::consts::PI;

/// Adds a sphereflake of recursion depth `level` (Haines, "A Proposal for Standard
/// Graphics Environments", IEEE CG&A 1987, the SPD `balls` database): a sphere with
/// nine children of a third of its radius resting on its surface, six around the
/// equator and three on top, each oriented away from its parent and recursing.
/// Returns the number of spheres added, [`sphereflake_count`]`(level)`.
pub fn sphereflake(
    b: &mut SceneBuilder,
    level: u32,
    center: Vec3,
    radius: f32,
    material: u32,
) -> usize {
    let before = b.spheres.len();
    b.spheres.cx.reserve(sphereflake_count(level));
    add_flake(b, level, center, radius, Vec3::Y, material);
    b.spheres.len() - before
}

/// `1 + 9 + ... + 9^level`: 1, 10, 91, 820, 7381, 66430 for levels 0..=5.
pub fn sphereflake_count(level: u32) -> usize {
    (0..=level).map(|k| 9usize.pow(k)).sum()
}

fn add_flake(
    b: &mut SceneBuilder,
    level: u32,
    center: Vec3,
    radius: f32,
    axis: Vec3,
    material: u32,
) {
    b.add_sphere(center, radius, material);
    if level == 0 {
        return;
    }
    let (t, bt) = orthonormal_basis(axis);
    let child_radius = radius / 3.0;
    // Children touch the parent: centre distance r + r/3.
    let dist = radius + child_radius;
    let mut child = |elevation: f32, azimuth: f32| {
        let dir = (elevation.cos() * (azimuth.cos() * t + azimuth.sin() * bt)
            + elevation.sin() * axis)
            .normalize();
        add_flake(
            b,
            level - 1,
            center + dist * dir,
            child_radius,
            dir,
            material,
        );
    };
    for k in 0..6 {
        child(0.0, k as f32 * PI / 3.0);
    }
    for k in 0..3 {
        child(PI / 3.0, PI / 6.0 + k as f32 * 2.0 * PI / 3.0);
    }
}

/// Branch-free orthonormal basis around unit `n` (Duff et al., JCGT 2017).
fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Adds a closed, watertight, bumpy sphere ("blob") of at least `triangles` triangles
/// (the nearest count the tessellation allows, within about `2 sqrt(triangles)` above),
/// with shared vertices and smooth vertex normals; a stand-in for scanned meshes such
/// as the Bunny at any size from 10^2 to 10^7 triangles. Returns the triangles added.
///
/// A UV sphere: `m` stacks of `nu` segments, single pole vertices, the seam closed by
/// index wrap-around, so every edge is shared by exactly two consistently oriented
/// (outward, counter-clockwise) triangles. `2 nu (m - 1)` triangles, `nu (m - 1) + 2`
/// vertices.
/// The radius is displaced by a smooth deterministic sum of sines (amplitude < 25 %),
/// so the surface has concave and convex regions like an organic model.
pub fn tessellated_mesh(
    b: &mut SceneBuilder,
    triangles: usize,
    center: Vec3,
    radius: f32,
    material: u32,
) -> usize {
    let (nu, m) = uv_sphere_resolution(triangles);
    let (positions, indices) = uv_sphere(nu, m, |dir| center + radius * blob_radius(dir) * dir);

    // Area-weighted vertex normals: the unnormalised face normal is twice the area.
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in &indices {
        let [p0, p1, p2] = t.map(|i| positions[i as usize]);
        let n = (p1 - p0).cross(p2 - p0);
        for i in t {
            normals[*i as usize] += n;
        }
    }
    for n in &mut normals {
        *n = n.normalize_or_zero();
    }
    b.add_mesh(&positions, &normals, &indices, material);
    indices.len()
}

/// A UV sphere of `nu` segments and `m` stacks with the vertex at unit direction `dir`
/// placed at `place(dir)`: single pole vertices, the seam closed by index wrap-around,
/// outward counter-clockwise triangles (see [`tessellated_mesh`]).
fn uv_sphere(nu: usize, m: usize, place: impl Fn(Vec3) -> Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let ring = |j: usize, k: usize| (1 + (j - 1) * nu + k % nu) as u32;
    let south = (1 + (m - 1) * nu) as u32;

    let mut positions = Vec::with_capacity(nu * (m - 1) + 2);
    positions.push(place(Vec3::Y));
    for j in 1..m {
        let theta = PI * j as f32 / m as f32;
        let (st, ct) = theta.sin_cos();
        for k in 0..nu {
            let phi = 2.0 * PI * k as f32 / nu as f32;
            let (sp, cp) = phi.sin_cos();
            positions.push(place(Vec3::new(st * cp, ct, st * sp)));
        }
    }
    positions.push(place(-Vec3::Y));

    let mut indices = Vec::with_capacity(2 * nu * (m - 1));
    for k in 0..nu {
        indices.push([0, ring(1, k + 1), ring(1, k)]);
    }
    for j in 1..m - 1 {
        for k in 0..nu {
            let (a, bb, c, d) = (
                ring(j, k),
                ring(j, k + 1),
                ring(j + 1, k),
                ring(j + 1, k + 1),
            );
            indices.push([a, bb, d]);
            indices.push([a, d, c]);
        }
    }
    for k in 0..nu {
        indices.push([south, ring(m - 1, k), ring(m - 1, k + 1)]);
    }
    (positions, indices)
}

/// Adds a coarse UV sphere of `segments` x `stacks` (at least 3 x 2) with the exact
/// sphere normals at its vertices: the classic low-polygon, smooth-shaded mesh on which
/// shadow rays leaving the flat facets shadow the lit side near the terminator (see
/// [`crate::geometry::terminator`]). Returns the triangles added,
/// `2 segments (stacks - 1)`.
pub fn low_poly_sphere(
    b: &mut SceneBuilder,
    segments: usize,
    stacks: usize,
    center: Vec3,
    radius: f32,
    material: u32,
) -> usize {
    let (nu, m) = (segments.max(3), stacks.max(2));
    let (positions, indices) = uv_sphere(nu, m, |dir| center + radius * dir);
    let normals: Vec<Vec3> = positions
        .iter()
        .map(|p| ((*p - center) / radius).normalize_or_zero())
        .collect();
    b.add_mesh(&positions, &normals, &indices, material);
    indices.len()
}

/// `(segments, stacks)` with `2 * segments * (stacks - 1) >= triangles` (the two pole
/// caps are one triangle per segment, the other rows two), close to it, and
/// segments ≈ 2 stacks so that quads are roughly square at the equator.
fn uv_sphere_resolution(triangles: usize) -> (usize, usize) {
    let rows = ((triangles as f64 / 4.0).sqrt().ceil() as usize).max(1);
    let nu = triangles.div_ceil(2 * rows).max(3);
    (nu, rows + 1)
}

/// Radius factor of the blob along unit direction `d`: smooth, deterministic, in [0.77, 1.23].
fn blob_radius(d: Vec3) -> f32 {
    1.0 + 0.12 * (3.0 * d.x + 0.5).sin() * (4.0 * d.y + 1.3).sin() * (3.5 * d.z + 0.2).sin()
        + 0.07 * (7.0 * d.x - 5.0 * d.z + 0.9).sin() * (6.0 * d.y + 0.4).cos()
        + 0.04 * (13.0 * d.y + 11.0 * d.z).sin()
}

/// Whitted's room ("An Improved Illumination Model for Shaded Display", 1980): a red and
/// yellow checkerboard floor, a mirror sphere behind a glass sphere (ior 1.5), two
/// point lights, a blue sky background; sets the camera.
pub fn whitted_room(b: &mut SceneBuilder) {
    let floor = b.add_material(Material {
        checker: Some(Checker {
            color_a: Vec3::new(0.9, 0.1, 0.05),
            color_b: Vec3::new(0.95, 0.85, 0.1),
            scale: 1.0,
        }),
        ..Material::diffuse("whitted_floor", Vec3::splat(0.8))
    });
    let mirror = b.add_material(Material {
        specular: Vec3::splat(0.5),
        shininess: 64.0,
        ..Material::mirror("whitted_mirror", Vec3::splat(0.85))
    });
    let glass = b.add_material(Material {
        specular: Vec3::splat(0.5),
        shininess: 128.0,
        ..Material::glass("whitted_glass", 1.5)
    });
    // Floor y = 0, x in [-5, 5], z in [-12, 4]; e1 = +z, e2 = +x so the normal is +y.
    b.add_quad(
        Vec3::new(-5.0, 0.0, -12.0),
        Vec3::new(0.0, 0.0, 16.0),
        Vec3::new(10.0, 0.0, 0.0),
        floor,
    );
    b.add_sphere(Vec3::new(0.9, 1.3, -2.0), 1.0, mirror);
    b.add_sphere(Vec3::new(-0.5, 1.0, 0.3), 0.75, glass);
    b.add_light(Light::Point {
        position: Vec3::new(4.0, 8.0, 5.0),
        intensity: Vec3::splat(100.0),
    });
    b.add_light(Light::Point {
        position: Vec3::new(-6.0, 6.0, 2.0),
        intensity: Vec3::splat(30.0),
    });
    b.background = Vec3::new(0.25, 0.45, 0.85);
    b.ambient = Vec3::splat(0.05);
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 1.6, 5.5),
        target: Vec3::new(0.0, 0.9, -0.5),
        up: Vec3::Y,
        vfov_deg: 45.0,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphereflake_counts_match_haines() {
        let expected = [1, 10, 91, 820, 7381, 66430];
        for (level, &n) in expected.iter().enumerate() {
            assert_eq!(sphereflake_count(level as u32), n);
            let mut b = SceneBuilder::new();
            assert_eq!(sphereflake(&mut b, level as u32, Vec3::ZERO, 1.0, 0), n);
            assert_eq!(b.spheres.len(), n);
        }
    }

    #[test]
    fn sphereflake_children_touch_parent_and_do_not_overlap_siblings() {
        let mut b = SceneBuilder::new();
        sphereflake(&mut b, 1, Vec3::ZERO, 3.0, 0);
        for i in 1..10 {
            let d = b.spheres.center(i).length();
            assert!((d - 4.0).abs() < 1e-5, "child {i} at distance {d}");
            assert!((b.spheres.radius[i] - 1.0).abs() < 1e-6);
            assert!(
                b.spheres.center(i).y > -1e-5,
                "children sit on the upper half"
            );
            for j in 1..i {
                assert!((b.spheres.center(i) - b.spheres.center(j)).length() > 2.0);
            }
        }
    }

    #[test]
    fn resolution_meets_request_closely() {
        for t in [1usize, 12, 100, 1000, 69_451, 1_000_000, 10_000_000] {
            let (nu, m) = uv_sphere_resolution(t);
            let got = 2 * nu * (m - 1);
            assert!(got >= t, "{t} -> {got}");
            assert!(got <= t.max(6) + 2 * m, "{t} -> {got}");
        }
    }

    #[test]
    fn blob_is_outward_oriented() {
        let mut b = SceneBuilder::new();
        tessellated_mesh(&mut b, 2000, Vec3::ZERO, 1.0, 0);
        // Divergence theorem: the signed volume of a closed outward mesh is positive.
        let vol: f32 = (0..b.mesh.len())
            .map(|t| {
                let [a, bb, c] = b.mesh.corners(t);
                a.dot(bb.cross(c)) / 6.0
            })
            .sum();
        assert!(vol > 3.0 && vol < 5.5, "volume {vol}");
    }

    #[test]
    fn whitted_room_finishes() {
        let mut b = SceneBuilder::new();
        whitted_room(&mut b);
        let s = b.finish().unwrap();
        assert!(s.features.glass && s.features.mirror && s.features.textures);
    }
}
